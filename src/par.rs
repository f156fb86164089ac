//! The host's loops split over the CPU's cores.

use std::sync::OnceLock;

/// The cores this process may use ([`std::thread::available_parallelism`],
/// 1 where unknown), read once: on Linux each call reads the cgroup's CPU
/// quota from `/proc` and `/sys`, which cost the contour's line searches
/// about 0.5 ms a frame when they asked every time (docs/performance.md).
pub fn cores() -> usize {
    static CORES: OnceLock<usize> = OnceLock::new();
    *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// `f` over the consecutive `chunk`-long parts of `items`, the last part on
/// the calling thread and each other one on a scoped thread of its own,
/// the results concatenated in order: the same as one pass over `items`.
/// A part whose thread cannot be started runs on the calling thread.
pub fn flat_map_chunks<T: Sync, U: Send>(
    items: &[T],
    chunk: usize,
    f: impl Fn(&[T]) -> Vec<U> + Sync,
) -> Vec<U> {
    let mut parts = items.chunks(chunk.max(1));
    let Some(last) = parts.next_back() else {
        return Vec::new();
    };
    let f = &f;
    std::thread::scope(|scope| {
        let started: Vec<_> = parts
            .map(|part| {
                let thread = std::thread::Builder::new()
                    .spawn_scoped(scope, move || f(part))
                    .ok();
                (part, thread)
            })
            .collect();
        let tail = f(last);
        let mut out = Vec::with_capacity(items.len());
        for (part, thread) in started {
            match thread.map(|t| t.join()) {
                Some(Ok(v)) => out.extend(v),
                // A part that panicked panics here again, with its message.
                Some(Err(_)) | None => out.extend(f(part)),
            }
        }
        out.extend(tail);
        out
    })
}

/// `f` over `items` split evenly over the cores (at most 8 parts), or in
/// one part on the calling thread when there is one core or fewer than
/// `min_items` items (a thread costs tens of microseconds): the same as
/// one pass over `items`.
pub fn flat_map_split<T: Sync, U: Send>(
    items: &[T],
    min_items: usize,
    f: impl Fn(&[T]) -> Vec<U> + Sync,
) -> Vec<U> {
    let threads = cores().min(8);
    if threads < 2 || items.len() < min_items {
        return f(items);
    }
    flat_map_chunks(items, items.len().div_ceil(threads), f)
}

/// A thread that runs as long as one end of its channel stays open (the
/// sender of its work, or the receiver of its results): dropped, it closes
/// that end, which ends the thread's loop, then joins the thread. The
/// contour's colour learner and the frames read ahead run on one each.
pub(crate) struct ChannelThread<E> {
    end: Option<E>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl<E> ChannelThread<E> {
    /// `body` on a new thread named `name`, kept while `end` is held.
    pub(crate) fn spawn(
        name: &str,
        end: E,
        body: impl FnOnce() + Send + 'static,
    ) -> std::io::Result<Self> {
        let thread = std::thread::Builder::new().name(name.into()).spawn(body)?;
        Ok(Self {
            end: Some(end),
            thread: Some(thread),
        })
    }

    /// The end of the channel held.
    pub(crate) fn end(&self) -> &E {
        self.end.as_ref().expect("held until dropped")
    }
}

impl<E> Drop for ChannelThread<E> {
    fn drop(&mut self) {
        self.end.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_give_one_pass_s_results_in_order() {
        let items: Vec<u32> = (0..1000).collect();
        let one = |p: &[u32]| {
            p.iter()
                .filter(|&&x| x % 3 != 0)
                .map(|&x| x * 2)
                .collect::<Vec<_>>()
        };
        let whole = one(&items);
        for chunk in [0, 1, 7, 333, 334, 999, 1000, 5000] {
            assert_eq!(flat_map_chunks(&items, chunk, one), whole, "chunk {chunk}");
        }
        assert!(flat_map_chunks(&[] as &[u32], 4, one).is_empty());
        for min_items in [0, 64, 1000, 1001] {
            assert_eq!(flat_map_split(&items, min_items, one), whole);
        }
        assert!(flat_map_split(&[] as &[u32], 0, one).is_empty());
        assert!(cores() >= 1);
        assert_eq!(cores(), cores());
    }
}
