//! The selection of the corners among the candidates on the GPU
//! (shaders/harris_select.wgsl, shaders/harris_select_small.wgsl), what
//! it gives back, and the refinement of corners the host selected.

use super::super::{Corner, merge};
use super::passes::{SELECT_ENTRIES, SMALL_CAP, SMALL_SELECT, Size, select_passes};
use super::{Detected, Harris};
use crate::features::FeatureError;
use crate::features::gpu_data::{Counters, RefineCorner};
use crate::gpu::{PassChain, WORKGROUP_1D, workgroups};

impl Harris {
    /// The most candidates the next selection takes on the GPU: the
    /// limit, at most [`SMALL_CAP`] in one workgroup.
    pub(super) fn select_limit_now(&self) -> usize {
        if self.small_selection() {
            self.select_limit.min(SMALL_CAP)
        } else {
            self.select_limit
        }
    }

    /// Whether the next selection runs in one workgroup a pass.
    pub(super) fn small_selection(&self) -> bool {
        self.tiled_select
            && self
                .small_select
                .unwrap_or(self.recent_candidates[self.kind] <= SMALL_SELECT)
    }

    /// Whether the next selection's merge runs in one workgroup (with
    /// the selection, or alone: [`super::HarrisGpuOptions::small_selection`]).
    pub(super) fn small_merge(&self) -> bool {
        self.small_selection()
            || (self.tiled_select
                && self.small_select.is_none()
                && self.config.max_corners <= SMALL_CAP)
    }

    /// Records the selection of the corners behind the map passes
    /// (`shaders/harris_select.wgsl`) into `chain`: three
    /// stages (selection, refinement, merge), several dispatches each, one thread an item
    /// (the O(n^2) ones tiled or not: [`super::HarrisGpuOptions::tiled_selection`]),
    /// sized on the GPU (`select_sizes`, then indirect dispatches).
    pub(super) fn encode_select(&mut self, chain: &mut PassChain) {
        let bind = self.select_bind.as_ref().expect("prepared");
        let sizes = self.sizes_bind.as_ref().expect("prepared");
        let args = self.select_args.get();
        let (small, small_merge) = (self.small_selection(), self.small_merge());
        if small {
            log::trace!("harris: the selection in one workgroup a pass");
        }
        let stages = select_passes(
            self.tiled_select,
            small,
            small_merge,
            self.config.refine_radius,
        );
        for (label, entries) in stages {
            let pass = chain.stage(label, self.timer.as_mut());
            for &e in entries {
                let size = SELECT_ENTRIES[e].1;
                pass.set_pipeline(&self.select[e]);
                pass.set_bind_group(0, if size == Size::One { sizes } else { bind }, &[]);
                match size {
                    Size::One => pass.dispatch_workgroups(1, 1, 1),
                    Size::Candidates => pass.dispatch_workgroups_indirect(args, 0),
                    Size::Selected => pass.dispatch_workgroups_indirect(args, 16),
                    Size::SelectedGroups => pass.dispatch_workgroups_indirect(args, 32),
                    Size::CandidatesSplit => pass.dispatch_workgroups_indirect(args, 48),
                    Size::SelectedSplit => pass.dispatch_workgroups_indirect(args, 64),
                    Size::Group => pass.dispatch_workgroups(1, 1, 1),
                    Size::Rounds => {
                        for _ in 0..self.merge_rounds {
                            pass.dispatch_workgroups_indirect(args, 16);
                        }
                    }
                }
            }
        }
    }

    /// The corners of a selection on the GPU from its counters and the
    /// first `part` of them read back (bytes of [`RefineCorner`]s): the
    /// rest read back where it kept more; where its merge left corners
    /// undecided, the selected corners (in the merge's order) read back
    /// and merged on the host.
    pub(super) fn selected_corners(
        &mut self,
        counters: &Counters,
        part: &[u8],
        slots: usize,
    ) -> Result<Detected, FeatureError> {
        let ctx = &self.ctx.clone();
        let corner = |r: &RefineCorner| Corner {
            x: r.x,
            y: r.y,
            score: r.score,
        };
        if counters.undecided > 0 {
            log::trace!(
                "harris: {} corners left to the host's merge",
                counters.undecided
            );
            let ordered: Vec<RefineCorner> = ctx.read_buffer(self.ordered.get(), slots)?;
            let corners = merge(
                ordered.iter().map(corner).collect(),
                self.config.merge_radius,
            );
            self.note_kept(corners.len());
            return Ok(Detected {
                corners,
                exported: false,
            });
        }
        let size = std::mem::size_of::<RefineCorner>();
        let kept = (counters.selected as usize).min(slots);
        self.note_kept(kept);
        let exported = kept * size <= part.len();
        let refined: Vec<RefineCorner> = if exported {
            bytemuck::pod_collect_to_vec(&part[..kept * size])
        } else {
            ctx.read_buffer(self.corners.get(), kept)?
        };
        Ok(Detected {
            corners: refined.iter().map(corner).collect(),
            exported,
        })
    }

    pub(super) fn refine(
        &mut self,
        w: usize,
        h: usize,
        corners: &[Corner],
    ) -> Result<Vec<Corner>, FeatureError> {
        let ctx = &self.ctx.clone();
        let n = corners.len();
        let p = self.params(w, h, n as u32);
        self.params.write(ctx, bytemuck::bytes_of(&p));
        let input: Vec<RefineCorner> = corners
            .iter()
            .map(|c| RefineCorner {
                x: c.x,
                y: c.y,
                score: c.score,
                status: 0.0,
            })
            .collect();
        ctx.write_buffer(self.corners.get(), 0, bytemuck::cast_slice(&input));
        let mut enc = ctx.encoder();
        {
            let mut passes = PassChain::new(ctx, &mut enc);
            let pass = passes.stage("refine", self.timer.as_mut());
            pass.set_pipeline(&self.refine);
            pass.set_bind_group(0, self.bind.as_ref().expect("prepared"), &[]);
            pass.dispatch_workgroups(workgroups(n as u32, WORKGROUP_1D), 1, 1);
        }
        let out: Vec<RefineCorner> = ctx.read_buffer_after(enc, self.corners.get(), n)?;
        Ok(out
            .iter()
            .map(|c| Corner {
                x: c.x,
                y: c.y,
                score: c.score,
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::super::super::{HarrisConfig, selected_starts};
    use super::*;
    use crate::features::gpu_data::{Candidate, MERGE_ROUNDS, SELECT_MAX};
    use crate::rng::Rng;

    impl Harris {
        /// The GPU's selection among `cands` in a `w x h` image whose
        /// gradients are all zero (a refinement keeps every corner at its
        /// start): the candidates written as NMS writes them, the
        /// selection's passes, the corners read back.
        fn select_candidates(
            &mut self,
            w: usize,
            h: usize,
            cands: &[Candidate],
        ) -> Result<Vec<Corner>, FeatureError> {
            self.prepare(w, h)?;
            let ctx = &self.ctx.clone();
            let p = self.params(w, h, 0);
            self.params.write(ctx, bytemuck::bytes_of(&p));
            let counters = Counters {
                max_bits: 0,
                count: cands.len() as u32,
                selected: 0,
                undecided: 0,
            };
            ctx.write_buffer(self.counters.get(), 0, bytemuck::bytes_of(&counters));
            if !cands.is_empty() {
                ctx.write_buffer(self.candidates.get(), 0, bytemuck::cast_slice(cands));
            }
            let mut enc = ctx.encoder();
            enc.clear_buffer(self.grad.get(), 0, None);
            self.encode_select(&mut PassChain::new(ctx, &mut enc));
            let counters: Counters = ctx.read_buffer_after(enc, self.counters.get(), 1)?[0];
            // The merge in one workgroup runs its rounds to the end.
            assert!(
                !self.small_merge() || counters.undecided == 0,
                "{} corners left undecided in one workgroup",
                counters.undecided
            );
            let slots = cands.len().min(self.config.max_corners);
            self.selected_corners(&counters, &[], slots)
                .map(|d| d.corners)
        }
    }

    /// `n` candidates at distinct pixels of `w x h`, clustered (so that
    /// merges chain and cells fill) where `dense`; scores drawn from four
    /// values where `ties`.
    fn candidates(
        rng: &mut Rng,
        n: usize,
        w: u32,
        h: u32,
        dense: bool,
        ties: bool,
    ) -> Vec<Candidate> {
        let mut seen = std::collections::HashSet::new();
        let mut out = Vec::new();
        let (cw, ch) = if dense {
            (w.min(24), h.min(24))
        } else {
            (w, h)
        };
        while out.len() < n && seen.len() < (cw * ch) as usize {
            let x = (rng.next_f64() * cw as f64) as u32 % cw;
            let y = (rng.next_f64() * ch as f64) as u32 % ch;
            if !seen.insert((x, y)) {
                continue;
            }
            let score = if ties {
                [0.25f32, 0.5, 0.75, 1.0][(rng.next_f64() * 4.0) as usize % 4]
            } else {
                (rng.next_f64() as f32).max(1e-6)
            };
            out.push(Candidate {
                x,
                y,
                score,
                _pad: 0,
            });
        }
        out
    }

    /// The host's selection and merge (the CPU reference's) of `cands`
    /// kept at their pixels.
    fn host_selection(cands: &[Candidate], cfg: &HarrisConfig) -> Vec<Corner> {
        merge(selected_starts(cands, cfg), cfg.merge_radius)
    }

    #[test]
    fn gpu_selection_is_the_hosts_bit_for_bit_on_random_candidates() {
        let ctx = crate::gpu::shared_test_context();
        let mut rng = Rng::new(7);
        let (w, h) = (200, 150);
        let (mut cases, mut smalls, mut small_merges) = (0, 0, 0);
        // One detector (its pipelines built once), its configuration set
        // for each case.
        let mut harris = Harris::new(ctx, HarrisConfig::default()).unwrap();
        for (case, (n, dense)) in [
            (0, false),
            (1, false),
            (37, false),
            (500, false),
            (400, true),
            (3000, false),
        ]
        .into_iter()
        .enumerate()
        {
            for grid in [0, 1, 16, 32] {
                for max in [1, 25, 900, 5000] {
                    for radius in [0.0, 1.5, 4.0] {
                        for ties in [false, true] {
                            // A sample of the combinations, every value of
                            // each parameter seen with each other's.
                            let key = n + grid as usize + max + (radius * 2.0) as usize;
                            if !(key + ties as usize).is_multiple_of(3) {
                                continue;
                            }
                            let cfg = HarrisConfig {
                                max_corners: max,
                                grid_cell: grid,
                                merge_radius: radius,
                                ..HarrisConfig::default()
                            };
                            harris.config = cfg.clone();
                            harris.set_select_limit(SELECT_MAX as usize);
                            // The four selections in turn: one thread an
                            // item, split over workgroups, one workgroup a
                            // pass (up to SMALL_SELECT candidates: beyond,
                            // its loops pass lavapipe's 65535 iterations),
                            // split with the merge in one workgroup (the
                            // default after a busy detection, where
                            // max_corners <= SMALL_CAP).
                            let mode = cases % 4;
                            let small = mode == 2 && n <= SMALL_SELECT;
                            harris.set_tiled_selection(mode > 0);
                            harris.set_small_selection(Some(small));
                            if mode == 3 {
                                harris.set_small_selection(None);
                                harris.recent_candidates[harris.kind] = usize::MAX;
                                assert!(!harris.small_selection());
                                assert_eq!(harris.small_merge(), max <= SMALL_CAP);
                                small_merges += harris.small_merge() as usize;
                            }
                            // Every other case without the parallel rounds:
                            // the host finishes the whole merge.
                            harris.merge_rounds = if (case + cases) % 2 == 0 {
                                0
                            } else {
                                MERGE_ROUNDS
                            };
                            let cands = candidates(&mut rng, n, w, h, dense, ties);
                            let got = harris
                                .select_candidates(w as usize, h as usize, &cands)
                                .unwrap();
                            let want = host_selection(&cands, &cfg);
                            let first = got.iter().zip(&want).position(|(g, w)| g != w);
                            assert!(
                                got == want,
                                "{n} candidates (dense {dense}, ties {ties}), grid {grid}, max {max}, radius {radius}, {} rounds, mode {mode}, small {small}: {} corners against the host's {}, first difference at {first:?}",
                                harris.merge_rounds,
                                got.len(),
                                want.len()
                            );
                            cases += 1;
                            smalls += small as usize;
                        }
                    }
                }
            }
        }
        assert!(cases > 100, "{cases} cases");
        assert!(smalls > 20, "{smalls} cases in one workgroup");
        assert!(
            small_merges > 20,
            "{small_merges} merges alone in one workgroup"
        );
    }
}
