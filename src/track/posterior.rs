//! The GLMB density the tracker carries from step to step: weighted hypotheses over shared
//! track entries, each entry one label's density under one association history.

use super::gaussian::Gaussian;
use crate::label::Label;

/// One track density of the posterior: a label with one association history.
#[derive(Debug, Clone)]
pub(crate) struct Entry<const N: usize> {
    pub label: Label,
    pub density: Gaussian<N>,
    /// Whether the last update associated an audio measurement that sounds now (see
    /// [`super::Scan::sounding`]); `speaking` is its probability.
    pub audio: bool,
    /// Probability of "on" of each detectability mode (voice, faces; see `modes`).
    pub modes: Vec<f64>,
    /// (scan, measurement) pairs used by the last update.
    pub assoc: Vec<(u16, u16)>,
    /// Time (s) since an update of this entry's history took a measurement of a camera (or
    /// of any sensor that is not audio); infinite when none did.
    pub unseen_s: f64,
    /// Probability that the track walks (`gait`).
    pub walking: f64,
    /// The density conditioned on standing and on walking (`gait`); None where both are
    /// `density` (a birth, or no gait).
    pub gait: Option<Box<[Gaussian<N>; 2]>>,
}

/// A GLMB density: weighted hypotheses over shared track entries, sorted by decreasing weight.
#[derive(Debug, Clone)]
pub(crate) struct Posterior<const N: usize> {
    pub entries: Vec<Entry<N>>,
    /// (log weight, start, len) of each hypothesis in `ids`.
    pub hyps: Vec<(f64, u32, u32)>,
    pub ids: Vec<u32>,
}

impl<const N: usize> Posterior<N> {
    /// The density with no track (certainly).
    pub fn empty() -> Self {
        Self {
            entries: Vec::new(),
            hyps: vec![(0.0, 0, 0)],
            ids: Vec::new(),
        }
    }

    /// Entry indices of hypothesis `h`.
    pub fn tracks(&self, h: usize) -> &[u32] {
        let (_, s, l) = self.hyps[h];
        &self.ids[s as usize..(s + l) as usize]
    }

    /// Normalised weight of hypothesis `h`.
    pub fn weight(&self, h: usize) -> f64 {
        self.hyps[h].0.exp()
    }
}
