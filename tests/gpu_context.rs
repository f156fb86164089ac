//! The GPU layer end to end on whatever adapter the tests run on (lavapipe
//! in CI): dispatch, readback, texture readback, timers, adapter selection.

use splattrack::gpu::{self, AdapterChoice, GpuContext, GpuError, GpuTimer};
use splattrack::rng::Rng;

fn ctx() -> &'static GpuContext {
    gpu::shared_test_context()
}

#[test]
fn saxpy_matches_cpu_on_random_inputs() {
    // Tolerance: one f32 rounding of |a x| + |y| (fma may run unfused).
    for n in [1usize, 63, 64, 65, 10_007] {
        let err = gpu::selftest::run(ctx(), n).unwrap();
        assert!(err <= 1.0, "n = {n}: max |gpu - cpu| = {err} eps");
    }
}

#[test]
fn texture_readback_removes_row_padding() {
    // 37 RGBA8 pixels per row = 148 bytes, padded to 256 in the copy.
    let (w, h) = (37u32, 11u32);
    let mut rng = Rng::new(9);
    let data: Vec<u8> = (0..w * h * 4).map(|_| rng.below(256) as u8).collect();
    let tex = ctx().device.create_texture(&wgpu::TextureDescriptor {
        label: Some("readback test"),
        size: wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::COPY_DST | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    ctx().queue.write_texture(
        tex.as_image_copy(),
        &data,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(w * 4),
            rows_per_image: Some(h),
        },
        tex.size(),
    );
    let back = ctx().read_texture(&tex, 4).unwrap();
    assert_eq!(back, data);
}

#[test]
fn read_buffer_refuses_overreads() {
    let b = ctx().buffer_init("small", &[1u32, 2, 3, 4], gpu::STORAGE_OUT);
    assert_eq!(ctx().read_buffer::<u32>(&b, 4).unwrap(), vec![1, 2, 3, 4]);
    assert!(matches!(
        ctx().read_buffer::<u32>(&b, 1000),
        Err(GpuError::Readback(_))
    ));
}

#[test]
fn read_buffers_reads_several_buffers_in_one_readback() {
    // Parts of any length (none, not a multiple of 4, whole buffers), the
    // bytes of each buffer's start, one wait for the GPU; an overread is
    // refused before anything is submitted.
    let c = own_ctx();
    let a = c.buffer_init("a", &[1u32, 2, 3, 4, 5], gpu::STORAGE_OUT);
    let b = c.buffer_init("b", &[7u8; 40], gpu::STORAGE_OUT);
    let bytes = |v: &[u32]| -> Vec<u8> { bytemuck::cast_slice(v).to_vec() };
    let before = c.stats().readbacks;
    let got = c
        .read_buffers(&[(&a, 6), (&b, 0), (&b, 40), (&a, 20)])
        .unwrap();
    assert_eq!(c.stats().readbacks - before, 1);
    assert_eq!(got[0], bytes(&[1, 2])[..6].to_vec());
    assert!(got[1].is_empty());
    assert_eq!(got[2], vec![7u8; 40]);
    assert_eq!(got[3], bytes(&[1, 2, 3, 4, 5]));
    assert!(matches!(
        c.read_buffers(&[(&a, 4), (&b, 41)]),
        Err(GpuError::Readback(_))
    ));
    assert_eq!(c.stats().readbacks - before, 1);
    assert!(c.read_buffers(&[]).unwrap().is_empty());
}

#[test]
fn a_readback_after_recorded_work_is_one_submission() {
    // `read_buffer_after` / `read_buffers_after`: the copies go behind
    // the caller's work in its encoder, so the work and its readback cost
    // one submission and one wait; the values are those the work wrote.
    // An overread is refused before anything is submitted, the caller's
    // work included (the buffer keeps its values).
    let c = own_ctx();
    let a = c.buffer_init("a", &[1u32, 2, 3, 4, 5], gpu::STORAGE_OUT);
    let b = c.buffer_init("b", &[9u32; 3], gpu::STORAGE_OUT);
    let (subs, reads) = (c.stats().submissions, c.stats().readbacks);
    let mut enc = c.encoder();
    enc.clear_buffer(&a, 0, Some(8));
    enc.copy_buffer_to_buffer(&b, 0, &a, 12, 4);
    let got: Vec<u32> = c.read_buffer_after(enc, &a, 5).unwrap();
    assert_eq!(got, [0, 0, 3, 9, 5]);
    assert_eq!(
        (c.stats().submissions - subs, c.stats().readbacks - reads),
        (1, 1)
    );

    let mut enc = c.encoder();
    enc.clear_buffer(&b, 4, None);
    let parts = c.read_buffers_after(enc, &[(&b, 12), (&a, 6)]).unwrap();
    assert_eq!(parts[0], bytemuck::cast_slice::<u32, u8>(&[9, 0, 0]));
    assert_eq!(parts[1], bytemuck::cast_slice::<u32, u8>(&[0, 0])[..6]);
    assert_eq!(
        (c.stats().submissions - subs, c.stats().readbacks - reads),
        (2, 2)
    );

    let mut enc = c.encoder();
    enc.clear_buffer(&a, 0, None);
    assert!(matches!(
        c.read_buffer_after::<u32>(enc, &a, 6),
        Err(GpuError::Readback(_))
    ));
    assert_eq!(
        (c.stats().submissions - subs, c.stats().readbacks - reads),
        (2, 2)
    );
    assert_eq!(c.read_buffer::<u32>(&a, 5).unwrap(), [0, 0, 3, 9, 5]);

    // Nothing to read: the work is submitted alone, without a wait.
    let mut enc = c.encoder();
    enc.clear_buffer(&a, 16, None);
    assert!(c.read_buffers_after(enc, &[(&a, 0)]).unwrap()[0].is_empty());
    assert_eq!(
        (c.stats().submissions - subs, c.stats().readbacks - reads),
        (4, 3)
    );
    assert_eq!(c.read_buffer::<u32>(&a, 5).unwrap(), [0, 0, 3, 9, 0]);
}

#[test]
fn a_batch_submits_a_chain_of_passes_with_its_readback() {
    // `GpuContext::batch`: work submitted within it waits for the next
    // readback and goes with it, in order, in one submission; the values
    // are those of submitting each step at once. Dropping the guard
    // submits what is left; guards nest; `wait` submits what is put off;
    // another thread's submissions are not batched.
    let c = own_ctx();
    let a = c.buffer_init("a", &[1u32, 2, 3, 4], gpu::STORAGE_OUT);
    let b = c.buffer_init("b", &[7u32; 4], gpu::STORAGE_OUT);
    let (subs, cbs) = (c.stats().submissions, c.stats().command_buffers);
    {
        let _batch = c.batch();
        // Each step reads what the one before wrote.
        step(&c, |e| e.copy_buffer_to_buffer(&a, 0, &b, 4, 8));
        step(&c, |e| e.clear_buffer(&a, 0, Some(8)));
        step(&c, |e| e.copy_buffer_to_buffer(&b, 8, &a, 4, 4));
        assert_eq!(c.stats().submissions, subs, "put off");
        let enc = c.encoder();
        let got: Vec<u32> = c.read_buffer_after(enc, &a, 4).unwrap();
        assert_eq!(got, [0, 2, 3, 4]);
        assert_eq!(c.stats().submissions - subs, 1, "one submission");
        assert_eq!(c.stats().command_buffers - cbs, 1, "one command buffer");
        assert_eq!(c.read_buffer::<u32>(&b, 4).unwrap(), [7, 1, 2, 7]);
        assert_eq!(c.stats().submissions - subs, 2);

        // Nested: the inner guard's end submits nothing.
        {
            let _inner = c.batch();
            step(&c, |e| e.clear_buffer(&b, 0, None));
        }
        assert_eq!(c.stats().submissions - subs, 2);

        // Another thread submits and reads at once (and takes the work
        // put off here with it: submitting earlier is always safe).
        let d = c.buffer_init("d", &[5u32; 4], gpu::STORAGE_OUT);
        std::thread::scope(|s| {
            s.spawn(|| {
                let mut enc = c.encoder();
                enc.copy_buffer_to_buffer(&a, 12, &d, 0, 4);
                c.submit(enc);
                assert_eq!(c.stats().submissions - subs, 3, "not batched");
            });
        });
        assert_eq!(c.read_buffer::<u32>(&b, 4).unwrap(), [0; 4]);
        assert_eq!(c.read_buffer::<u32>(&d, 4).unwrap(), [4, 5, 5, 5]);
        assert_eq!(c.read_buffer::<u32>(&a, 4).unwrap(), [0, 2, 3, 4]);
        let done = c.stats().submissions;
        step(&c, |e| e.clear_buffer(&a, 0, Some(4)));
        c.wait().unwrap();
        assert_eq!(
            c.stats().submissions - done,
            1,
            "wait submits what is put off"
        );
        step(&c, |e| e.clear_buffer(&a, 4, Some(4)));
        assert_eq!(c.stats().submissions - done, 1);
    }
    // The guard's end submitted the last clear.
    let done = c.stats().submissions;
    let got: Vec<u32> = c.read_buffer(&a, 4).unwrap();
    assert_eq!(got, [0, 0, 3, 4]);
    assert_eq!(
        c.stats().submissions - done,
        1,
        "no batch: the readback alone"
    );
}

#[test]
fn a_batch_records_its_work_into_one_encoder() {
    // Within a batch `GpuContext::encoder` lends the batch's one encoder,
    // holding the work put off so far: a chain of steps and its readback
    // make one command buffer. An encoder dropped unsubmitted (an error
    // path) leaves its work with the batch; one made before the batch
    // began goes after the batch's work so far. Outside a batch every
    // encoder is a command buffer of its own.
    let c = own_ctx();
    let a = c.buffer_init("a", &[1u32, 2, 3, 4], gpu::STORAGE_OUT);
    let b = c.buffer_init("b", &[7u32; 4], gpu::STORAGE_OUT);
    let mut early = c.encoder();
    early.copy_buffer_to_buffer(&a, 0, &b, 0, 16);
    let (subs, cbs) = (c.stats().submissions, c.stats().command_buffers);
    {
        let _batch = c.batch();
        step(&c, |e| e.clear_buffer(&a, 0, Some(4)));
        {
            let mut enc = c.encoder();
            enc.clear_buffer(&a, 4, Some(4));
        }
        // After both clears: b = [0, 0, 3, 4].
        c.submit(early);
        assert_eq!(c.stats().submissions, subs, "put off");
        assert_eq!(c.read_buffer::<u32>(&b, 4).unwrap(), [0, 0, 3, 4]);
        assert_eq!(
            (
                c.stats().submissions - subs,
                c.stats().command_buffers - cbs
            ),
            (1, 3),
            "the batch's encoder, the early one, the readback's"
        );
        let cbs = c.stats().command_buffers;
        step(&c, |e| e.clear_buffer(&b, 12, None));
        step(&c, |e| e.copy_buffer_to_buffer(&a, 8, &b, 0, 4));
        let mut enc = c.encoder();
        enc.clear_buffer(&b, 4, Some(4));
        assert_eq!(
            c.read_buffer_after::<u32>(enc, &b, 4).unwrap(),
            [3, 0, 3, 0]
        );
        assert_eq!(c.stats().command_buffers - cbs, 1, "one command buffer");
        assert_eq!(c.stats().submissions - subs, 2);
    }
    let cbs = c.stats().command_buffers;
    step(&c, |e| e.clear_buffer(&a, 0, None));
    step(&c, |e| e.clear_buffer(&b, 0, None));
    assert_eq!(c.stats().command_buffers - cbs, 2, "no batch: one each");
    assert_eq!(c.read_buffer::<u32>(&b, 4).unwrap(), [0; 4]);
}

#[test]
#[should_panic(expected = "lent already")]
fn a_second_encoder_while_the_batchs_is_lent_is_refused() {
    // Its work could not be ordered after the lent encoder's.
    let c = own_ctx();
    let _batch = c.batch();
    let _first = c.encoder();
    let _second = c.encoder();
}

#[test]
fn a_put_off_readback_goes_with_the_next_one() {
    // `GpuContext::read_buffer_later`: the copy is taken behind the work
    // before it (later work may overwrite the buffer), nothing waits, and
    // the thread's next readback maps it too: one wait for both, its bytes
    // then at hand. Waited for before any other readback, it reads alone.
    // Another thread's readback does not carry it, nor any readback once
    // it is dropped. Its staging buffers are kept: the steady state makes
    // none.
    let c = own_ctx();
    let a = c.buffer_init("a", &[1u32, 2, 3, 4, 5], gpu::STORAGE_OUT);
    let b = c.buffer_init("b", &[7u32; 4], gpu::STORAGE_OUT);
    let copy = |from: &wgpu::Buffer, to: &wgpu::Buffer| {
        let mut enc = c.encoder();
        enc.copy_buffer_to_buffer(from, 0, to, 0, 16);
        enc
    };
    for round in 0..3 {
        let (reads, made) = (c.stats().readbacks, c.stats().buffers_created);
        // b = a's first four, put off; then a is cleared.
        let pending = c.read_buffer_later(copy(&a, &b), &b, 12).unwrap();
        let mut enc = c.encoder();
        enc.clear_buffer(&a, 0, Some(8));
        c.submit(enc);
        assert_eq!(c.stats().readbacks, reads, "round {round}: nothing waits");
        let got: Vec<u32> = c.read_buffer(&a, 5).unwrap();
        assert_eq!(got, [0, 0, 3, 4, 5]);
        assert_eq!(c.stats().readbacks - reads, 1, "round {round}: one wait");
        let bytes = pending.wait(&c).unwrap();
        assert_eq!(bytemuck::pod_collect_to_vec::<u8, u32>(&bytes), [1, 2, 3]);
        assert_eq!(
            c.stats().readbacks - reads,
            1,
            "round {round}: the bytes at hand"
        );
        if round > 0 {
            assert_eq!(
                c.stats().buffers_created,
                made,
                "round {round}: staging kept"
            );
        }
        // Restore a.
        c.queue
            .write_buffer(&a, 0, bytemuck::cast_slice(&[1u32, 2, 3, 4, 5]));
    }
    // Waited for first: a readback of its own.
    let reads = c.stats().readbacks;
    let pending = c.read_buffer_later(copy(&a, &b), &b, 16).unwrap();
    let bytes = pending.wait(&c).unwrap();
    assert_eq!(
        bytemuck::pod_collect_to_vec::<u8, u32>(&bytes),
        [1, 2, 3, 4]
    );
    assert_eq!(c.stats().readbacks - reads, 1);
    // Within a batch: put off with the batch, one submission with the
    // readback.
    let (reads, subs) = (c.stats().readbacks, c.stats().submissions);
    {
        let _batch = c.batch();
        let pending = c.read_buffer_later(copy(&a, &b), &b, 16).unwrap();
        assert_eq!(c.stats().submissions, subs, "put off");
        let got: Vec<u32> = c.read_buffer(&a, 1).unwrap();
        assert_eq!(got, [1]);
        assert_eq!(
            (c.stats().submissions - subs, c.stats().readbacks - reads),
            (1, 1),
            "one submission, one wait"
        );
        let bytes = pending.wait(&c).unwrap();
        assert_eq!(
            bytemuck::pod_collect_to_vec::<u8, u32>(&bytes),
            [1, 2, 3, 4]
        );
    }
    // Another thread's readback leaves this thread's put-off one alone.
    let reads = c.stats().readbacks;
    let pending = c.read_buffer_later(copy(&a, &b), &b, 8).unwrap();
    std::thread::scope(|s| {
        s.spawn(|| {
            let got: Vec<u32> = c.read_buffer(&a, 2).unwrap();
            assert_eq!(got, [1, 2]);
        });
    });
    let bytes = pending.wait(&c).unwrap();
    assert_eq!(bytemuck::pod_collect_to_vec::<u8, u32>(&bytes), [1, 2]);
    assert_eq!(
        c.stats().readbacks - reads,
        2,
        "the other thread's, then its own"
    );
    // Dropped unwaited: no readback maps it.
    let read = c.stats().bytes_read;
    drop(c.read_buffer_later(copy(&a, &b), &b, 16).unwrap());
    let got: Vec<u32> = c.read_buffer(&a, 1).unwrap();
    assert_eq!(got, [1]);
    assert_eq!(c.stats().bytes_read - read, 4, "its bytes not read");
    // An overread is refused, nothing submitted.
    let subs = c.stats().submissions;
    assert!(c.read_buffer_later(copy(&a, &b), &b, 20).is_err());
    assert_eq!(c.stats().submissions, subs);
}

#[test]
fn device_has_the_limits_the_splatter_needs() {
    // Four RGBA32F targets = 64 bytes per sample; wgpu's default is 32.
    assert!(
        ctx().limits.max_color_attachment_bytes_per_sample >= 64,
        "{}",
        ctx().describe()
    );
    assert!(ctx().features.contains(wgpu::Features::FLOAT32_BLENDABLE));
}

#[test]
fn timer_reports_pass_durations() {
    let c = ctx();
    let mut timer = GpuTimer::new(c, 4);
    let n = 1 << 16;
    let saxpy = gpu::selftest::Saxpy::new(c, 1.5, &vec![1.0; n], &vec![2.0; n]).unwrap();
    let mut enc = c.encoder();
    for label in ["first", "second"] {
        saxpy.dispatch(&mut enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: timer.compute_pass(label),
        }));
    }
    timer.resolve(&mut enc);
    c.submit(enc);
    let report = timer.read(c).unwrap();
    let y: Vec<f32> = c.read_buffer(saxpy.y(), n).unwrap();
    assert!(y.iter().all(|&v| v == 5.0), "two passes of y += 1.5 x");
    if timer.enabled() {
        assert_eq!(report.passes.len(), 2);
        for (label, ms) in &report.passes {
            assert!(
                ms.is_finite() && *ms >= 0.0 && *ms < 10_000.0,
                "{label}: {ms} ms"
            );
        }
        assert!(report.get("first").is_some() && report.total_ms() >= 0.0);
    } else {
        assert!(report.passes.is_empty());
    }
}

/// A `PassChain` records its stages in one compute pass where they are
/// untimed (a new one only after the encoder was asked for) and in one a
/// stage where a timer times them, with the timer's labels; each dispatch
/// sees what the one before wrote in either case (wgpu's barriers between
/// dispatches of one pass). Exact: sums of small integers.
#[test]
fn a_pass_chain_records_one_pass_untimed_and_one_a_stage_timed() {
    let c = own_ctx();
    let n = 1 << 14;
    let saxpy = gpu::selftest::Saxpy::new(&c, 1.0, &vec![1.0; n], &vec![0.0; n]).unwrap();
    let mut enc = c.encoder();
    let mut chain = gpu::PassChain::new(&c, &mut enc);
    for label in ["a", "b", "c"] {
        saxpy.dispatch(chain.stage(label, None));
    }
    assert_eq!(chain.passes(), 1, "untimed stages share a pass");
    chain.encoder().clear_buffer(saxpy.y(), 0, Some(4));
    for label in ["d", "e"] {
        saxpy.dispatch(chain.stage(label, None));
    }
    assert_eq!(chain.passes(), 2, "a new pass after the encoder's work");
    drop(chain);
    let v: Vec<f32> = c.read_buffer_after(enc, saxpy.y(), n).unwrap();
    assert_eq!(v[0], 2.0, "cleared after three, then two more");
    assert!(v[1..].iter().all(|&v| v == 5.0), "{:?}", &v[..8]);

    let mut timer = GpuTimer::new(&c, 4);
    if !timer.enabled() {
        panic!("{}: no timestamp queries", c.describe());
    }
    let mut enc = c.encoder();
    let mut chain = gpu::PassChain::new(&c, &mut enc);
    for label in ["f", "g", "h"] {
        saxpy.dispatch(chain.stage(label, Some(&mut timer)));
    }
    assert_eq!(chain.passes(), 3, "timed stages each a pass");
    drop(chain);
    let t = timer.resolve_later(&c, &mut enc).unwrap();
    let v: Vec<f32> = c.read_buffer_after(enc, saxpy.y(), n).unwrap();
    assert!(v[1..].iter().all(|&v| v == 8.0), "{:?}", &v[..8]);
    let labels: Vec<String> = t.wait(&c).passes.into_iter().map(|(l, _)| l).collect();
    assert_eq!(labels, ["f", "g", "h"]);
}

/// Timings read later come with the next readback: timing passes adds no
/// wait for the GPU and no submission of its own (`track --profile`
/// counts the loop's own), whether the resolve goes into the timed work's
/// encoder (`resolve_later`) or behind work already submitted
/// (`read_later`, carried by the next submission, even past the end of a
/// batch with nothing of its own).
#[test]
fn timings_come_with_the_next_readback() {
    let c = own_ctx();
    let mut timer = GpuTimer::new(&c, 4);
    if !timer.enabled() {
        panic!("{}: no timestamp queries", c.describe());
    }
    let n = 1 << 12;
    let saxpy = gpu::selftest::Saxpy::new(&c, 1.0, &vec![1.0; n], &vec![0.0; n]).unwrap();
    let y = saxpy.y();
    let record = |enc: &mut wgpu::CommandEncoder, timer: &mut GpuTimer, labels: &[&str]| {
        for label in labels {
            saxpy.dispatch(&mut enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(label),
                timestamp_writes: timer.compute_pass(label),
            }));
        }
    };
    let counts = || (c.stats().readbacks, c.stats().submissions);
    let check = |report: &splattrack::gpu::TimerReport, labels: &[&str]| {
        let got: Vec<&str> = report.passes.iter().map(|(l, _)| l.as_str()).collect();
        assert_eq!(got, labels);
        for (label, ms) in &report.passes {
            assert!(
                ms.is_finite() && *ms >= 0.0 && *ms < 10_000.0,
                "{label}: {ms} ms"
            );
        }
    };

    // Resolved into the timed work's encoder, read with its readback.
    let (r0, s0) = counts();
    let mut enc = c.encoder();
    record(&mut enc, &mut timer, &["a", "b"]);
    let t = timer.resolve_later(&c, &mut enc).unwrap();
    let v: Vec<f32> = c.read_buffer_after(enc, y, n).unwrap();
    assert!(v.iter().all(|&v| v == 2.0));
    assert_eq!(counts(), (r0 + 1, s0 + 1));
    check(&t.wait(&c), &["a", "b"]);
    assert_eq!(counts(), (r0 + 1, s0 + 1), "the timings waited again");

    // Behind submitted work: no submission of their own, not even at the
    // end of a batch that has nothing else; the next readback brings them.
    let mut enc = c.encoder();
    record(&mut enc, &mut timer, &["c"]);
    c.submit(enc);
    let t = timer.read_later(&c).unwrap();
    drop(c.batch());
    assert_eq!(counts(), (r0 + 1, s0 + 2));
    let mut enc = c.encoder();
    record(&mut enc, &mut timer, &["d"]);
    c.submit(enc);
    let mut later = timer.read_later(&c).unwrap();
    // The readback's submission carries both resolves.
    let v: Vec<f32> = c.read_buffer(y, n).unwrap();
    assert!(v.iter().all(|&v| v == 4.0));
    assert_eq!(counts(), (r0 + 2, s0 + 4));
    check(&t.wait(&c), &["c"]);
    later.append(Default::default());
    assert_eq!(counts(), (r0 + 2, s0 + 4), "the timings waited again");

    // Timings never read cost one wait when asked for, for all.
    let mut enc = c.encoder();
    record(&mut enc, &mut timer, &["e"]);
    c.submit(enc);
    let mut more = timer.read_later(&c).unwrap();
    let mut enc = c.encoder();
    record(&mut enc, &mut timer, &["f"]);
    c.submit(enc);
    more.append(timer.read_later(&c).unwrap());
    later.append(more);
    check(&later.wait(&c), &["d", "e", "f"]);
    assert_eq!(counts(), (r0 + 3, s0 + 7));
}

#[test]
fn adapter_choice_parses_and_unknown_names_fail_clearly() {
    assert_eq!("CPU".parse::<AdapterChoice>().unwrap(), AdapterChoice::Cpu);
    assert_eq!(
        "discrete".parse::<AdapterChoice>().unwrap(),
        AdapterChoice::Discrete
    );
    assert!("".parse::<AdapterChoice>().is_err());
    let err = GpuContext::new(&AdapterChoice::Name("no-such-gpu-xyz".into())).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("no-such-gpu-xyz") && msg.contains("available"),
        "{msg}"
    );
}

#[test]
fn invalid_shaders_are_errors_not_panics() {
    static BROKEN: splattrack::shaders::Shader = splattrack::shaders::Shader {
        name: "no_such_shader",
        parts: &[("shaders/none.wgsl", "fn main( {")],
        constants: &[],
    };
    assert!(matches!(
        ctx().compute_pipeline(&BROKEN, "main"),
        Err(GpuError::Shader { .. })
    ));
    assert!(matches!(
        ctx().compute_pipeline(&splattrack::gpu::selftest::SHADER, "no_such_entry"),
        Err(GpuError::Validation { .. })
    ));
}

/// A fresh device (not the shared one: these tests break theirs).
/// Records `f` into an encoder of `c` and submits it.
fn step(c: &GpuContext, f: impl FnOnce(&mut wgpu::CommandEncoder)) {
    let mut enc = c.encoder();
    f(&mut enc);
    c.submit(enc);
}

fn own_ctx() -> GpuContext {
    splattrack::gpu::own_test_context()
}

#[test]
fn sizes_above_the_adapters_limits_are_refused_before_allocation() {
    let c = ctx();
    let huge = c.limits.max_buffer_size.saturating_add(1);
    // Checked at once...
    let e = c
        .try_buffer("harris corners", huge, gpu::STORAGE_OUT)
        .unwrap_err();
    assert!(matches!(e, GpuError::TooLarge(_)), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("harris corners") && msg.contains("max_buffer_size"),
        "{msg}"
    );
    let over_binding = c.limits.max_storage_buffer_binding_size + 16;
    if over_binding <= c.limits.max_buffer_size {
        let e = c
            .try_buffer("storage", over_binding, gpu::STORAGE_OUT)
            .unwrap_err()
            .to_string();
        assert!(e.contains("max_storage_buffer_binding_size"), "{e}");
    }
    // One past the adapter's own limit (16384 on lavapipe, 32768 on an
    // H200: a fixed size would pass on one of them).
    let side = c.limits.max_texture_dimension_2d + 1;
    let e = c
        .check_texture_size("render targets", side, side)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!("{side} x {side}")) && e.contains("max_texture_dimension_2d"),
        "{e}"
    );
    assert!(c.check_texture_size("ok", 640, 480).is_ok());
    assert!(c.try_buffer("fine", 1024, gpu::STORAGE_OUT).is_ok());
}

#[test]
fn gpu_errors_outside_a_scope_become_typed_errors_not_panics() {
    let c = own_ctx();
    // The infallible buffer() with a size a 16 GB corner list would ask
    // for: nothing allocated, and the next wait reports it.
    let size = 16_000_000_000u64.max(c.limits.max_buffer_size.saturating_add(1));
    let b = c.buffer("corners of 1e9", size, gpu::STORAGE_OUT);
    assert_eq!(b.size(), 16);
    let e = c.wait().unwrap_err();
    assert!(matches!(e, GpuError::TooLarge(_)), "{e}");
    // Reported once; the device is fine afterwards.
    c.wait().unwrap();
    // A real wgpu validation error outside any scope (a texture above the
    // limit): wgpu's default handler would panic; ours records it.
    let too_big = c.limits.max_texture_dimension_2d + 1;
    let _t = c.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("too big"),
        size: wgpu::Extent3d {
            width: too_big,
            height: 1,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let e = c.wait().unwrap_err();
    assert!(matches!(e, GpuError::Uncaptured(_)), "{e}");
    assert!(e.to_string().starts_with("GPU error"), "{e}");
    c.wait().unwrap();
    // Inside catch(): a typed validation error naming the context.
    let e = c
        .catch("the test texture", || {
            c.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("too big"),
                size: wgpu::Extent3d {
                    width: too_big,
                    height: 1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8Unorm,
                usage: wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        })
        .unwrap_err();
    assert!(e.to_string().contains("the test texture"), "{e}");
}

#[test]
fn a_lost_device_ends_work_with_an_error() {
    let c = own_ctx();
    let b = c.buffer_init("data", &[1.0f32, 2.0, 3.0, 4.0], gpu::STORAGE_OUT);
    assert_eq!(c.read_buffer::<f32>(&b, 4).unwrap(), [1.0, 2.0, 3.0, 4.0]);
    c.device.destroy();
    let e = c.read_buffer::<f32>(&b, 4).unwrap_err();
    assert!(matches!(e, GpuError::DeviceLost(_)), "{e}");
    assert!(e.to_string().contains("device was lost"), "{e}");
    assert!(c.wait().is_err());
}

#[test]
fn memory_report_counts_live_buffers() {
    let c = own_ctx();
    let before = c.memory_report();
    let bufs: Vec<_> = (0..5)
        .map(|_| c.buffer("count me", 1 << 20, gpu::STORAGE_OUT))
        .collect();
    let during = c.memory_report();
    assert_eq!(during.buffers - before.buffers, 5, "{before:?} {during:?}");
    assert!(
        during.buffer_bytes - before.buffer_bytes >= 5 << 20,
        "{before:?} {during:?}"
    );
    drop(bufs);
    c.wait().unwrap();
    let after = c.memory_report();
    assert_eq!(after.buffers, before.buffers, "{before:?} {after:?}");
}

/// A `BindCache` binds anew only when one of its buffers is another one
/// (by identity; a clone of the same buffer is the same) than those of
/// the last two sets it bound (a pass fed in turn by two stages binds
/// nothing anew); a third set takes the least recently used one's place.
#[test]
fn a_bind_cache_binds_again_only_for_other_buffers() {
    let c = ctx();
    let layout = c.bind_group_layout(
        "bind cache test",
        &[
            gpu::compute_entry(0, gpu::storage(false)),
            gpu::compute_entry(1, gpu::storage(false)),
        ],
    );
    let make = |label| c.buffer(label, 64, gpu::STORAGE_OUT);
    let (a, b, other) = (make("a"), make("b"), make("other"));
    let mut cache = gpu::BindCache::<2>::default();
    let binds = std::cell::Cell::new(0);
    // Gets the bind group of `bufs`; the binds made so far.
    let mut get = |bufs: [&wgpu::Buffer; 2]| {
        cache
            .get([bufs[0].clone(), bufs[1].clone()], |bs| {
                binds.set(binds.get() + 1);
                c.bind_buffers("bind cache test", &layout, &[&bs[0], &bs[1]])
            })
            .unwrap();
        binds.get()
    };
    assert_eq!(get([&a, &b]), 1);
    assert_eq!(get([&a, &b]), 1);
    assert_eq!(get([&a, &other]), 2);
    assert_eq!(get([&a, &other]), 2);
    // Two sets in turn: both held.
    for _ in 0..3 {
        assert_eq!(get([&a, &b]), 2);
        assert_eq!(get([&a, &other]), 2);
    }
    // A third set evicts the least recently used ([a, b]), not [a, other].
    assert_eq!(get([&b, &a]), 3);
    assert_eq!(get([&a, &other]), 3);
    assert_eq!(get([&a, &b]), 4);
}

/// wgpu checks each indirect dispatch's arguments on the GPU only where
/// asked (`WGPU_VALIDATION_INDIRECT_CALL`) or on DX12: the kernels that
/// write them keep them within the limits, so corners and splats are the
/// same bit for bit either way. The corners come from the split selection
/// (its passes sized by indirect dispatches), the splats from the compute
/// splatter with large splats (their list and `finish`'s bounding box
/// dispatched indirectly).
#[test]
fn indirect_dispatches_give_the_same_results_without_wgpus_validation() {
    use splattrack::features::{Harris, HarrisConfig, SELECT_MAX, patterns};
    use splattrack::geometry::{Intrinsics, look_at};
    use splattrack::model::shapes;
    use splattrack::splat::{
        Attribute, Attributes, Backend, GpuModel, SplatParams, SplatTargets, Splatter, cpu,
    };

    let asked = std::env::var_os(gpu::VALIDATE_INDIRECT_ENV).is_some();
    let shared = ctx();
    assert_eq!(
        shared.validates_indirect,
        asked || shared.info.backend == wgpu::Backend::Dx12
    );
    let choice = match AdapterChoice::from_env().unwrap() {
        AdapterChoice::Auto => AdapterChoice::Cpu,
        c => c,
    };
    let img = patterns::smooth_noise(203, 157, 1.1, 4);
    let mut rng = Rng::new(99);
    let mut model = shapes::random_cloud(&mut rng, glam::Vec3::ZERO, 1.0, 60, 0.2, 0.6);
    let small = shapes::random_cloud(&mut rng, glam::Vec3::ZERO, 1.0, 2000, 0.005, 0.03);
    model.positions.extend(&small.positions);
    model.normals.extend(&small.normals);
    model.radii.extend(&small.radii);
    if let (Some(c), Some(d)) = (&mut model.colors, &small.colors) {
        c.extend(d);
    }
    let cam = Intrinsics::new(160, 120, 150.0, 150.0, 80.0, 60.0);
    let pose = look_at(
        &nalgebra::Vector3::new(0.3, -0.2, 3.0),
        &nalgebra::Vector3::zeros(),
        &nalgebra::Vector3::new(0.0, 1.0, 0.0),
    );
    let big = (0..model.len())
        .filter(|&i| model.radii[i] as f64 * cam.fx / 3.5 > 16.0)
        .count();
    assert!(big >= 5, "{big} large splats");
    let run = |validate: bool| {
        let c = GpuContext::with_indirect_validation(&choice, validate).unwrap();
        assert_eq!(c.validates_indirect, validate);
        let mut harris = Harris::new(&c, HarrisConfig::default()).unwrap();
        harris.set_options(splattrack::features::HarrisGpuOptions {
            select_limit: Some(SELECT_MAX as usize),
            tiled_selection: Some(true),
            ..harris.options()
        });
        let corners = harris.detect(&img, None).unwrap();
        let splatter = Splatter::with_params(
            &c,
            SplatParams {
                backend: Backend::Compute,
                ..Default::default()
            },
        )
        .unwrap();
        let gm = GpuModel::new(&c, &model).unwrap();
        let mut t = SplatTargets::new(&c, cam.width, cam.height);
        splatter
            .render(&c, &gm, &cam, &pose, Attributes::ALL, &mut t)
            .unwrap();
        let images: Vec<Vec<u32>> = [Attribute::Color, Attribute::Depth, Attribute::Motion]
            .iter()
            .map(|&a| {
                let im = splatter.read(&c, &t, a).unwrap();
                im.data.iter().map(|v| v.to_bits()).collect()
            })
            .collect();
        (corners, images)
    };
    let (with, with_images) = run(true);
    let (without, without_images) = run(false);
    assert!(with.len() > 100, "{} corners", with.len());
    assert_eq!(with, without);
    // The render is the CPU reference's where it covers (not a blank one).
    let reference = cpu::splat(&model, &cam, &pose, &SplatParams::default()).unwrap();
    let covered = reference
        .resolve(Attribute::Depth)
        .data
        .iter()
        .filter(|v| v.is_finite() && **v > 0.0)
        .count();
    assert!(covered > 1000, "{covered} covered pixels");
    assert_eq!(with_images, without_images);
}

/// A `Uniform` uploads only bytes that differ from its last upload, and
/// the context counts both; what the GPU reads is always the last written,
/// batched or not.
#[test]
fn a_uniform_uploads_only_what_changed() {
    let c = own_ctx();
    let usage = wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_SRC;
    let mut u = gpu::Uniform::with_usage(&c, "test uniform", 16, usage);
    let before = c.stats();
    let read = |c: &GpuContext, u: &gpu::Uniform| -> Vec<u32> {
        let out = c.buffer(
            "uniform copy",
            16,
            wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
        );
        let mut enc = c.encoder();
        enc.copy_buffer_to_buffer(u.buffer(), 0, &out, 0, 16);
        c.read_buffer_after::<u32>(enc, &out, 4).unwrap()
    };
    assert!(u.write(&c, bytemuck::bytes_of(&[1u32, 2, 3, 4])));
    assert!(!u.write(&c, bytemuck::bytes_of(&[1u32, 2, 3, 4])));
    assert_eq!(read(&c, &u), [1, 2, 3, 4]);
    {
        // In a batch: A, then B, then A again (written: it differs from
        // B), then A once more (skipped): the GPU reads A.
        let _batch = c.batch();
        assert!(u.write(&c, bytemuck::bytes_of(&[5u32, 6, 7, 8])));
        assert!(u.write(&c, bytemuck::bytes_of(&[1u32, 2, 3, 4])));
        assert!(!u.write(&c, bytemuck::bytes_of(&[1u32, 2, 3, 4])));
    }
    assert_eq!(read(&c, &u), [1, 2, 3, 4]);
    assert!(u.write(&c, bytemuck::bytes_of(&[0u32, 0, 0, 9])));
    assert_eq!(read(&c, &u), [0, 0, 0, 9]);
    let done = c.stats().since(&before);
    assert_eq!((done.uploads, done.uploads_skipped), (4, 2));
}
