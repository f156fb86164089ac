//! A pair of foreground and background colour histograms, and the
//! object's probability of each bin.

/// One pair of normalised histograms, with the per-bin terms the line
/// search reads.
#[derive(Debug, Clone, PartialEq)]
pub struct Histograms {
    pub(super) foreground: Vec<f32>,
    pub(super) background: Vec<f32>,
    pub(super) learned: bool,
    /// Per bin: the object probability `p` (as
    /// [`ColourModel::foreground_probability`]), `ln p` and `ln (1 - p)`,
    /// kept up to date by every update (the line search needs the
    /// logarithms of every sample).
    pub(super) terms: Vec<[f64; 3]>,
}

impl Histograms {
    pub(super) fn new(n: usize) -> Self {
        let mut h = Self {
            foreground: vec![0.0; n],
            background: vec![0.0; n],
            learned: false,
            terms: Vec::new(),
        };
        h.update_terms();
        h
    }

    pub(super) fn probability_of_bin(&self, b: usize) -> f32 {
        let (f, g) = (self.foreground[b], self.background[b]);
        if f + g <= 0.0 {
            0.5
        } else {
            (f / (f + g)).clamp(0.02, 0.98)
        }
    }

    pub(super) fn update_terms(&mut self) {
        // A scene's colours fill few of the bins: the empty ones (0.5)
        // share one value, computed once.
        // Refilled in place: no allocation after the first.
        let half = [0.5, 0.5f64.ln(), 0.5f64.ln()];
        let mut terms = std::mem::take(&mut self.terms);
        terms.clear();
        terms.extend((0..self.foreground.len()).map(|b| {
            if self.foreground[b] + self.background[b] <= 0.0 {
                return half;
            }
            let p = self.probability_of_bin(b) as f64;
            [p, p.ln(), (1.0 - p).ln()]
        }));
        self.terms = terms;
    }

    /// Blends in one frame's counts (`rate`; the first time they are
    /// taken whole) when each side holds at least `least` pixels.
    pub(super) fn blend(&mut self, fg: &[f32], bg: &[f32], least: f32, rate: f32) {
        let (nf, nb) = (fg.iter().sum::<f32>(), bg.iter().sum::<f32>());
        if nf < least.max(f32::MIN_POSITIVE) || nb < least.max(f32::MIN_POSITIVE) {
            return;
        }
        let rate = if self.learned { rate } else { 1.0 };
        for (h, v) in self.foreground.iter_mut().zip(fg) {
            *h = (1.0 - rate) * *h + rate * v / nf;
        }
        for (h, v) in self.background.iter_mut().zip(bg) {
            *h = (1.0 - rate) * *h + rate * v / nb;
        }
        self.learned = true;
        self.update_terms();
    }
}

impl Histograms {
    /// [`ColourModel::foreground_probability`] `p` of bin `b`, with `ln p`
    /// and `ln (1 - p)`.
    pub(super) fn terms(&self, b: usize) -> [f64; 3] {
        self.terms[b]
    }
}
