//! The scene's truth standing in for a stage (`--oracle-tracks`, `--oracle-pitch`): the true
//! sources as track estimates and separator targets, and their true pitch.

use crate::dsp::{VoicePitch, Yin};
use crate::label::Label;
use crate::scene::Truth;
use crate::separate::{KnownPitch, PitchPart, SeparatorConfig, Target};

use super::stages::Estimate;

/// The label the oracle gives to true source `i` (its streams and tracks carry it).
pub fn source_label(i: usize) -> Label {
    Label::new(0, i as u32)
}

/// True sources present at `t` as estimates (for `--oracle-tracks`).
pub fn estimates(truth: &Truth, t: f64) -> Vec<Estimate> {
    truth
        .sources
        .iter()
        .enumerate()
        .filter_map(|(i, s)| {
            let p = s.position_at(t)?;
            let h = 0.05;
            let a = s.position_at(t - h).unwrap_or(p);
            let b = s.position_at(t + h).unwrap_or(p);
            let span = if s.exists_at(t - h) && s.exists_at(t + h) {
                2.0 * h
            } else {
                h
            };
            Some(Estimate {
                label: source_label(i),
                position: p,
                velocity: (b - a) / span,
                existence: 1.0,
                speaking: if s.is_active(t) { 1.0 } else { 0.0 },
                covariance: None,
            })
        })
        .collect()
}

/// True sources present at `t` as separator targets, with their true pitch when `pitch` is
/// given (`--oracle-pitch`).
pub fn targets(truth: &Truth, t: f64, activity: f64, pitch: Option<&OraclePitch>) -> Vec<Target> {
    estimates(truth, t)
        .into_iter()
        .map(|e| Target {
            label: e.label,
            position: e.position,
            direction_only: false,
            speaking: e.speaking,
            activity,
            pitch: pitch.map(|p| p.known(e.label.index as usize, t)),
        })
        .collect()
}

/// The true sources' pitch (`--oracle-pitch`): each source image's voice read by YIN, one
/// frame per separator hop, centred where the separator's frames are, and the part of it the
/// separator is handed.
#[derive(Debug, Clone, PartialEq)]
pub struct OraclePitch {
    hop_s: f64,
    tracks: Vec<Vec<VoicePitch>>,
    part: PitchPart,
}

impl OraclePitch {
    /// Pitch tracks of every source of `truth` at `sample_rate` Hz with the separator's framing
    /// and F0 range; the error names a source without a signal.
    pub fn new(
        truth: &Truth,
        sample_rate: u32,
        cfg: &SeparatorConfig,
        part: PitchPart,
    ) -> Result<Self, String> {
        let fs = f64::from(sample_rate);
        let h = &cfg.post_filter.harmonic;
        let yin = Yin::new(fs, h.f0_min_hz, h.f0_max_hz, cfg.frame);
        let tracks = truth
            .sources
            .iter()
            .map(|s| {
                s.signal
                    .as_deref()
                    .map(|x| yin.track(x, cfg.hop))
                    .ok_or_else(|| format!("truth source {:?} has no signal", s.id))
            })
            .collect::<Result<_, _>>()?;
        Ok(Self {
            hop_s: cfg.hop.max(1) as f64 / fs,
            tracks,
            part,
        })
    }

    /// The part of source `i`'s pitch at time `t` (s) that the separator is handed.
    pub fn known(&self, i: usize, t: f64) -> KnownPitch {
        KnownPitch::new(self.part, self.at(i, t))
    }

    /// Source `i`'s pitch in the frame nearest time `t` (s); unvoiced outside its signal.
    pub fn at(&self, i: usize, t: f64) -> VoicePitch {
        let j = (t / self.hop_s).round();
        if j.is_nan() || j < 0.0 {
            return VoicePitch::default();
        }
        self.tracks
            .get(i)
            .and_then(|tr| tr.get(j as usize))
            .copied()
            .unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use crate::scene::TruthSource;

    fn source(id: &str, signal: Option<Vec<f32>>) -> TruthSource {
        TruthSource {
            id: id.into(),
            signal,
            trajectory: vec![
                (0.0, Vec3::new(1.0, 1.0, 1.5)),
                (2.0, Vec3::new(1.0, 1.0, 1.5)),
            ],
            active: vec![(0.5, 2.0)],
        }
    }

    #[test]
    fn oracle_pitch_reads_each_sources_voice_at_the_frame_times() {
        let fs = 16000u32;
        // Silent for half a second, then a 150 Hz voice.
        let voice: Vec<f32> = (0..2 * fs as usize)
            .map(|i| {
                let t = i as f64 / f64::from(fs);
                if t < 0.5 {
                    0.0
                } else {
                    (1..10)
                        .map(|h| (std::f64::consts::TAU * 150.0 * f64::from(h) * t).sin())
                        .sum::<f64>() as f32
                }
            })
            .collect();
        let cfg = SeparatorConfig::default();
        let truth = Truth {
            sources: vec![source("s1", Some(voice))],
        };
        let p =
            OraclePitch::new(&truth, fs, &cfg, PitchPart::Both).expect("every source has a signal");
        assert_eq!(p.at(0, 0.2), VoicePitch::default());
        let v = p.at(0, 1.0);
        assert!(
            (v.f0 / 150.0 - 1.0).abs() < 0.005 && v.voicing == 1.0,
            "{v:?}"
        );
        // Outside the signal, and for an unknown source: unvoiced.
        assert_eq!(p.at(0, 5.0), VoicePitch::default());
        assert_eq!(p.at(0, -1.0), VoicePitch::default());
        assert_eq!(p.at(3, 1.0), VoicePitch::default());
        let with_pitch = targets(&truth, 1.0, 1.0, Some(&p));
        assert_eq!(with_pitch[0].pitch, Some(KnownPitch::Both(v)));
        // A part of the pitch hands over that part only.
        for (part, known) in [
            (PitchPart::F0, KnownPitch::F0(v.f0)),
            (PitchPart::Voicing, KnownPitch::Voicing(v.voicing)),
        ] {
            let p = OraclePitch::new(&truth, fs, &cfg, part).expect("every source has a signal");
            assert_eq!(targets(&truth, 1.0, 1.0, Some(&p))[0].pitch, Some(known));
        }
        assert_eq!(targets(&truth, 1.0, 1.0, None)[0].pitch, None);

        let missing = Truth {
            sources: vec![source("s1", None)],
        };
        let err =
            OraclePitch::new(&missing, fs, &cfg, PitchPart::Both).expect_err("s1 has no signal");
        assert!(err.contains("\"s1\""), "{err}");
    }
}
