//! Reverberation time of a measured or simulated room response by Schroeder backward
//! integration (ISO 3382): the energy decay curve is fitted by a line between two levels.

/// Reverberation time (s) of `response` from the slope of its Schroeder energy decay curve
/// between `-5 dB` and `-(5 + range_db) dB` (`range_db` 20 gives T20, 30 gives T30), extrapolated
/// to 60 dB. `None` when the curve never falls that far or the response is silent.
pub fn schroeder_rt60(response: &[f64], sample_rate: f64, range_db: f64) -> Option<f64> {
    let curve = energy_decay_db(response)?;
    let (hi, lo) = (-5.0, -5.0 - range_db);
    let first = curve.iter().position(|&d| d <= hi)?;
    let last = curve.iter().position(|&d| d <= lo)?;
    if last <= first + 1 {
        return None;
    }
    // Least-squares line through (t, dB) over the fitting range.
    let n = (last - first + 1) as f64;
    let (mut st, mut sd, mut stt, mut std_) = (0.0, 0.0, 0.0, 0.0);
    for (i, &d) in curve[first..=last].iter().enumerate() {
        let t = (first + i) as f64 / sample_rate;
        st += t;
        sd += d;
        stt += t * t;
        std_ += t * d;
    }
    let slope = (n * std_ - st * sd) / (n * stt - st * st);
    (slope < 0.0).then(|| -60.0 / slope)
}

/// The Schroeder energy decay curve in dB (0 dB at the start), `None` for a silent response.
pub fn energy_decay_db(response: &[f64]) -> Option<Vec<f64>> {
    let mut acc = 0.0;
    let mut curve = vec![0.0; response.len()];
    for (c, v) in curve.iter_mut().zip(response).rev() {
        acc += v * v;
        *c = acc;
    }
    let total = *curve.first()?;
    if !(total > 0.0 && total.is_finite()) {
        return None;
    }
    Some(
        curve
            .iter()
            .map(|e| 10.0 * (e / total).max(1e-30).log10())
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_the_decay_of_an_exponential_envelope() {
        // Noise-free exponential: amplitude falls 60 dB in 0.4 s.
        let fs = 16000.0;
        let h: Vec<f64> = (0..16000usize)
            .map(|n| {
                let t = n as f64 / fs;
                10f64.powf(-3.0 * t / 0.4) * if n.is_multiple_of(2) { 1.0 } else { -1.0 }
            })
            .collect();
        let t20 = schroeder_rt60(&h, fs, 20.0).unwrap();
        assert!((t20 - 0.4).abs() < 0.01, "{t20}");
        assert!(schroeder_rt60(&[0.0; 100], fs, 20.0).is_none());
    }
}
