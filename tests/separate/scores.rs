//! Measures of separation quality: energies, SI-SDR and SIR, per source and averaged.

use avsep::dsp::Complex;

use crate::fixtures::{FS, Mixture, Run};

/// Energy (sum of squares) of a signal.
pub fn energy(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum()
}

/// Decibels of a power ratio, floored far below any measured level.
pub fn db(x: f64) -> f64 {
    10.0 * x.max(1e-300).log10()
}

/// Scale-invariant SDR (dB) of `est` against `truth`.
pub fn si_sdr(est: &[f64], truth: &[f64]) -> f64 {
    let dot: f64 = est.iter().zip(truth).map(|(a, b)| a * b).sum();
    let alpha = dot / energy(truth).max(1e-300);
    let target: f64 = truth.iter().map(|t| (alpha * t).powi(2)).sum();
    let noise: f64 = est
        .iter()
        .zip(truth)
        .map(|(e, t)| (e - alpha * t).powi(2))
        .sum();
    db(target / noise.max(1e-300))
}

/// Signal-to-interference ratio (dB) of label `i` from its output's parts.
fn sir(parts: &[Vec<f64>], i: usize, sources: usize, from: usize) -> f64 {
    let n = parts[i].len();
    let interf: Vec<f64> = (from..n)
        .map(|t| (0..sources).filter(|&j| j != i).map(|j| parts[j][t]).sum())
        .collect();
    db(energy(&parts[i][from..]) / energy(&interf).max(1e-300))
}

/// Per-source SI-SDR and SIR, unprocessed (reference microphone) and processed, from `skip_s`.
pub struct Scores {
    pub si_sdr_in: Vec<f64>,
    pub si_sdr_out: Vec<f64>,
    pub sir_in: Vec<f64>,
    pub sir_out: Vec<f64>,
}

impl Scores {
    /// Scores of every source.
    pub fn of(mixture: &Mixture, run: &Run, skip_s: f64) -> Self {
        Self::of_tracked(mixture, run, skip_s, mixture.sources())
    }

    /// Scores of the first `tracked` sources (the others are interferers nobody tracks).
    pub fn of_tracked(mixture: &Mixture, run: &Run, skip_s: f64, tracked: usize) -> Self {
        let from = (skip_s * FS) as usize;
        let ns = mixture.sources();
        let mut s = Scores {
            si_sdr_in: vec![],
            si_sdr_out: vec![],
            sir_in: vec![],
            sir_out: vec![],
        };
        let ref_parts: Vec<Vec<f64>> = mixture.parts.iter().map(|p| p[0].clone()).collect();
        for i in 0..tracked {
            let truth = &mixture.truth(i)[from..];
            s.si_sdr_in.push(si_sdr(&mixture.mix[0][from..], truth));
            s.si_sdr_out.push(si_sdr(&run.out[i][from..], truth));
            if ns > 1 {
                s.sir_in.push(sir(&ref_parts, i, ns, from));
                if !run.parts[i].is_empty() {
                    s.sir_out.push(sir(&run.parts[i], i, ns, from));
                }
            }
        }
        s
    }

    fn mean(v: &[f64]) -> f64 {
        v.iter().sum::<f64>() / v.len().max(1) as f64
    }

    /// Mean SI-SDR gain (dB) over the tracked sources.
    pub fn si_sdr_improvement(&self) -> f64 {
        Self::mean(&self.si_sdr_out) - Self::mean(&self.si_sdr_in)
    }

    /// Mean SIR gain (dB) over the tracked sources.
    pub fn sir_improvement(&self) -> f64 {
        Self::mean(&self.sir_out) - Self::mean(&self.sir_in)
    }

    /// One aligned line of the means and gains, headed by `name`.
    pub fn line(&self, name: &str) -> String {
        format!(
            "{name:<28} SI-SDR in {:6.2} out {:6.2} (+{:5.2})  SIR in {:6.2} out {:6.2} (+{:5.2})",
            Self::mean(&self.si_sdr_in),
            Self::mean(&self.si_sdr_out),
            self.si_sdr_improvement(),
            Self::mean(&self.sir_in),
            Self::mean(&self.sir_out),
            self.sir_improvement()
        )
    }
}

/// Energy of a spectrum.
pub fn energy_c(x: &[Complex]) -> f64 {
    x.iter().map(|v| v.norm_sqr()).sum()
}
