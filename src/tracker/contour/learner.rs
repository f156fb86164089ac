//! The contour's colour learning off the tracking thread.
//!
//! After a tracked frame the contour learns the frame's colours at its
//! pose ([`ColourModel::learn_around`]: about 2.5 ms a frame on the real
//! cube, the largest block of the contour's host work). Nothing reads
//! those histograms before the next frame's contour step, so the learning
//! runs on a worker thread while the next frame's features, IT and KF
//! steps run, and the contour step waits for it. The worker computes
//! exactly what the tracking thread would (the same function on the same
//! inputs): the poses are the same bit for bit either way
//! (`tests/contour.rs`).
//!
//! The worker is started on the first learning and keeps its buffers (a
//! copy of the frame, the coverage mask) from frame to frame. Where no
//! thread can be started, or the worker is lost, learning runs on the
//! tracking thread, with the same results (a lost worker takes the
//! histograms with it: they start afresh, with an error logged).

use super::colour::ColourModel;
use crate::par::ChannelThread;
use nalgebra::Vector2;
use std::sync::{Mutex, mpsc};
use std::time::{Duration, Instant};

/// What one learning needs (besides the model and buffers): the frame's
/// region, the margin, the rate and the object's projected centre, as
/// [`ColourModel::learn_around`] takes them.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Lesson {
    pub rect: (usize, usize, usize, usize),
    pub margin: usize,
    pub rate: f32,
    pub centre: Option<Vector2<f64>>,
}

/// A learning handed to the worker: the model and the buffers go there
/// and come back.
struct Job {
    model: ColourModel,
    frame: image::RgbImage,
    mask: Vec<bool>,
    lesson: Lesson,
    /// How long the learning took.
    took: Duration,
}

impl Job {
    fn run(&mut self) {
        let t = Instant::now();
        let l = self.lesson;
        self.model
            .learn_around(&self.frame, &self.mask, l.rect, l.margin, l.rate, l.centre);
        self.took = t.elapsed();
    }
}

/// The worker thread and its two queues.
struct Worker {
    /// Closing it (dropping the worker) ends the thread's loop.
    jobs: ChannelThread<mpsc::Sender<Job>>,
    /// Behind a lock only to keep the tracker `Sync`.
    done: Mutex<mpsc::Receiver<Job>>,
}

impl Worker {
    fn start() -> std::io::Result<Self> {
        let (jobs, inbox) = mpsc::channel::<Job>();
        let (outbox, done) = mpsc::channel::<Job>();
        let jobs = ChannelThread::spawn("splattrack-colours", jobs, move || {
            while let Ok(mut job) = inbox.recv() {
                job.run();
                if outbox.send(job).is_err() {
                    break;
                }
            }
        })?;
        Ok(Self {
            jobs,
            done: Mutex::new(done),
        })
    }
}

/// The contour's colour model, learnt on the worker between frames.
pub(crate) struct Colours {
    /// The model, while no learning is out (else an empty stand-in).
    model: ColourModel,
    /// Whether the worker holds the model.
    out: bool,
    /// Bins and sectors of a fresh model.
    shape: (u32, usize),
    worker: Option<Worker>,
    /// Learn on the worker (else on the calling thread).
    background: bool,
    /// Buffers back from the worker, for the next learning.
    spare_frame: Vec<u8>,
    spare_mask: Vec<bool>,
    /// Time spent learning, and waiting for the worker, since
    /// [`Colours::take_times`].
    learnt: Duration,
    waited: Duration,
}

impl Colours {
    /// Fresh histograms of `bins` per channel and `sectors` sectors
    /// ([`ColourModel::with_sectors`]), learnt in the background.
    pub fn new(bins: u32, sectors: usize) -> Self {
        Self {
            model: ColourModel::with_sectors(bins, sectors),
            out: false,
            shape: (bins, sectors),
            worker: None,
            background: true,
            spare_frame: Vec::new(),
            spare_mask: Vec::new(),
            learnt: Duration::ZERO,
            waited: Duration::ZERO,
        }
    }

    /// The time spent learning (wherever it ran) and the time the caller
    /// waited for the worker to finish, since the last call.
    pub fn take_times(&mut self) -> (Duration, Duration) {
        let t = (self.learnt, self.waited);
        (self.learnt, self.waited) = (Duration::ZERO, Duration::ZERO);
        t
    }

    /// Learn on the worker (`true`, the default) or on the calling thread.
    /// The histograms are the same either way.
    pub(crate) fn set_background(&mut self, on: bool) {
        self.background = on;
    }

    /// The model, once any learning out is done.
    pub fn model(&mut self) -> &mut ColourModel {
        self.settle();
        &mut self.model
    }

    /// Starts afresh (any learning out is dropped).
    pub fn reset(&mut self) {
        self.settle();
        self.model = ColourModel::with_sectors(self.shape.0, self.shape.1);
    }

    /// Learns `frame` with the object covering `mask` (the frame's size)
    /// on the calling thread, once any learning out is done.
    pub fn learn_here(&mut self, frame: &image::RgbImage, mask: &[bool], lesson: Lesson) {
        self.settle();
        let t = Instant::now();
        let l = lesson;
        self.model
            .learn_around(frame, mask, l.rect, l.margin, l.rate, l.centre);
        self.learnt += t.elapsed();
    }

    /// Learns `frame` with the object covering `mask` (the frame's size):
    /// on the worker, which takes the mask and leaves a spare buffer of
    /// the same role in its place, or here.
    pub fn learn(&mut self, frame: &image::RgbImage, mask: &mut Vec<bool>, lesson: Lesson) {
        self.settle();
        if self.background && self.worker.is_none() {
            match Worker::start() {
                Ok(w) => self.worker = Some(w),
                Err(e) => {
                    log::warn!("no thread for the colour learning ({e}); learning on this one");
                    self.background = false;
                }
            }
        }
        let sender = match (&self.worker, self.background) {
            (Some(w), true) => Some(w.jobs.end()),
            _ => None,
        };
        // (A copy of an image's own pixels always makes an image.)
        let copy = sender.and_then(|_| {
            let mut pixels = std::mem::take(&mut self.spare_frame);
            pixels.clear();
            pixels.extend_from_slice(frame.as_raw());
            image::RgbImage::from_raw(frame.width(), frame.height(), pixels)
        });
        let (Some(sender), Some(copy)) = (sender, copy) else {
            self.learn_here(frame, mask, lesson);
            return;
        };
        let job = Job {
            model: std::mem::replace(&mut self.model, ColourModel::new(0)),
            frame: copy,
            mask: std::mem::replace(mask, std::mem::take(&mut self.spare_mask)),
            lesson,
            took: Duration::ZERO,
        };
        match sender.send(job) {
            Ok(()) => self.out = true,
            Err(mpsc::SendError(mut job)) => {
                // The worker is gone: learn here.
                log::error!("the colour learning's thread has stopped; learning on this one");
                self.worker = None;
                self.background = false;
                job.run();
                self.take_back(job, mask);
            }
        }
    }

    /// Waits for the learning out, if any, and takes the model back.
    fn settle(&mut self) {
        if !self.out {
            return;
        }
        self.out = false;
        let t = Instant::now();
        let back = self.worker.as_ref().map(|w| {
            let done = w.done.lock().unwrap_or_else(|e| e.into_inner());
            done.recv()
        });
        self.waited += t.elapsed();
        match back {
            Some(Ok(job)) => {
                self.learnt += job.took;
                self.model = job.model;
                self.spare_frame = job.frame.into_raw();
                self.spare_mask = job.mask;
            }
            _ => {
                log::error!(
                    "the colour learning's thread stopped with the histograms; \
                     they start afresh, learnt on this thread from now on"
                );
                self.worker = None;
                self.background = false;
                self.model = ColourModel::with_sectors(self.shape.0, self.shape.1);
            }
        }
    }

    /// A job run here: its model, its mask back in `mask`.
    fn take_back(&mut self, job: Job, mask: &mut Vec<bool>) {
        self.learnt += job.took;
        self.model = job.model;
        self.spare_frame = job.frame.into_raw();
        self.spare_mask = std::mem::replace(mask, job.mask);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame of blocks of colour and a disc of coverage.
    fn scene(seed: u32) -> (image::RgbImage, Vec<bool>) {
        let (w, h) = (96u32, 80u32);
        let frame = image::RgbImage::from_fn(w, h, |x, y| {
            let v = (x / 7 * 37 + y / 5 * 91 + seed * 13) % 256;
            image::Rgb([v as u8, (v * 3 % 256) as u8, (255 - v) as u8])
        });
        let mask = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (x - 47.5 - seed as f64).hypot(y - 40.2) < 25.0
            })
            .collect();
        (frame, mask)
    }

    /// Embedders move trackers across threads and share them behind
    /// locks: the worker's queues must not take that away.
    #[test]
    fn the_colours_stay_send_and_sync() {
        fn send_sync<T: Send + Sync>() {}
        send_sync::<Colours>();
    }

    #[test]
    fn learning_in_the_background_gives_the_same_histograms() {
        let mut here = Colours::new(8, 4);
        here.set_background(false);
        let mut there = Colours::new(8, 4);
        for seed in 0..6 {
            let (frame, mask) = scene(seed);
            let lesson = Lesson {
                rect: (5, 4, 90, 75),
                margin: 2,
                rate: 0.3,
                centre: Some(Vector2::new(47.5 + seed as f64, 40.2)),
            };
            let mut m1 = mask.clone();
            here.learn(&frame, &mut m1, lesson);
            let mut m2 = mask.clone();
            there.learn(&frame, &mut m2, lesson);
            // The worker holds the model and the mask: the caller's buffer
            // is a spare one now.
            assert!(there.out);
            assert_ne!(m2, mask);
            assert_eq!(m1, mask, "learning here leaves the mask");
            assert_eq!(here.model(), there.model(), "frame {seed}");
            assert!(there.model().is_learned());
            // Both timed the learning; only the worker's caller waited.
            let (learnt, waited) = there.take_times();
            assert!(learnt > Duration::ZERO);
            assert!(waited >= Duration::ZERO);
            let (learnt, waited) = here.take_times();
            assert!(learnt > Duration::ZERO);
            assert_eq!(waited, Duration::ZERO);
            assert_eq!(here.take_times(), (Duration::ZERO, Duration::ZERO));
        }
        // A reset drops the learning out.
        let (frame, mut mask) = scene(9);
        let lesson = Lesson {
            rect: (0, 0, 95, 79),
            margin: 1,
            rate: 0.5,
            centre: None,
        };
        there.learn(&frame, &mut mask, lesson);
        there.reset();
        assert!(!there.model().is_learned());
        assert_eq!(there.model(), &ColourModel::with_sectors(8, 4));
    }
}
