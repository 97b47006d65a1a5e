//! Scene measurements: how well the candidates match the truth, frame by frame.

use avsep::dsp::{Complex, FrameGeometry, Stft, StreamingStft};
use avsep::eval::ospa::{OspaParams, ospa};
use avsep::geometry::{Vec3, angle_diff, azimuth_of, deg};
use avsep::localize::{ArrayObservation, Localizer, LocalizerConfig};
use avsep::scene::{Scene, Truth, TruthSource};

/// Figures of one array over a scene.
#[derive(Debug, Default)]
pub struct Report {
    /// Localisation frames.
    pub frames: usize,
    /// (frame, talker) pairs in which the talker speaks for at least half the frame.
    pub active: usize,
    /// Of those, how many have a direction candidate within 5 degrees of azimuth.
    pub hits_5deg: usize,
    /// Active pairs in which the talker's image at the reference microphone, in the
    /// localiser's band, is within 10 dB of its mean over its active frames (audible there).
    pub audible: usize,
    /// Of those, how many have a direction candidate within 5 degrees of azimuth.
    pub audible_hits_5deg: usize,
    /// Frames with an active talker, counting only the talker loudest in the band.
    pub dominant: usize,
    /// Of those, how many have a direction candidate within 5 degrees of azimuth.
    pub dominant_hits_5deg: usize,
    /// Azimuth error (degrees) of the nearest candidate, per active pair with candidates.
    pub azimuth_errors: Vec<f64>,
    /// OSPA (c = 1 m, p = 1) of the position candidates per frame, against the active talkers.
    pub ospa: Vec<f64>,
    /// Cardinality part of each frame's OSPA (c |m - n| / max(m, n)).
    pub ospa_card: Vec<f64>,
    /// Same, only frames in which somebody talks.
    pub ospa_speech: Vec<f64>,
    /// Activity in frames with and without speech.
    pub activity_speech: Vec<f64>,
    /// Activity in frames without speech.
    pub activity_quiet: Vec<f64>,
    /// Direction and position candidates per frame (sums).
    pub doas: usize,
    /// Position candidates over all frames.
    pub points: usize,
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

impl Report {
    /// One line of figures.
    pub fn summary(&self) -> String {
        format!(
            "frames {}, active talker-frames {}, within 5 deg {:.1} % (audible {} of them: {:.1} %, loudest talker {:.1} %), median azimuth error {:.2} deg \
             (over {} talker-frames with candidates), mean OSPA {:.3} m (cardinality {:.3}, speech frames {:.3} m), \
             activity speech {:.2} / quiet {:.2} (speech frames > 0.5: {:.1} %, quiet frames > 0.5: {:.1} %), doas/frame {:.2}, points/frame {:.2}",
            self.frames,
            self.active,
            100.0 * self.hits_5deg as f64 / self.active.max(1) as f64,
            self.audible,
            100.0 * self.audible_hits_5deg as f64 / self.audible.max(1) as f64,
            100.0 * self.dominant_hits_5deg as f64 / self.dominant.max(1) as f64,
            median(&self.azimuth_errors),
            self.azimuth_errors.len(),
            mean(&self.ospa),
            mean(&self.ospa_card),
            mean(&self.ospa_speech),
            mean(&self.activity_speech),
            mean(&self.activity_quiet),
            100.0 * self.activity_speech.iter().filter(|a| **a > 0.5).count() as f64
                / self.activity_speech.len().max(1) as f64,
            100.0 * self.activity_quiet.iter().filter(|a| **a > 0.5).count() as f64
                / self.activity_quiet.len().max(1) as f64,
            self.doas as f64 / self.frames.max(1) as f64,
            self.points as f64 / self.frames.max(1) as f64,
        )
    }

    /// Fraction of active talker-frames found within 5 degrees.
    pub fn hit_rate(&self) -> f64 {
        self.hits_5deg as f64 / self.active.max(1) as f64
    }

    /// Median azimuth error (degrees) of the nearest candidate.
    pub fn median_azimuth_error(&self) -> f64 {
        median(&self.azimuth_errors)
    }

    /// Mean OSPA over all frames.
    pub fn mean_ospa(&self) -> f64 {
        mean(&self.ospa)
    }
}

/// Runs the localiser over the scene's audio in non-overlapping frames and scores array
/// `array` against the truth.
pub fn evaluate(scene: &Scene, cfg: &LocalizerConfig, array: usize) -> Report {
    let layout = &scene.layout;
    let audio = scene.audio.as_ref().expect("scene has audio");
    let truth = scene.truth.as_ref().expect("scene has truth");
    let mut loc = Localizer::new(layout, cfg, 1).expect("valid config");
    let frame = loc.frame_size();
    let fs = f64::from(layout.sample_rate);
    let channels: Vec<Vec<f64>> = (0..audio.channels)
        .map(|c| audio.channel(c).iter().map(|&v| f64::from(v)).collect())
        .collect();
    let mut stft = StreamingStft::new(FrameGeometry { frame, hop: frame }, channels.len());
    let centre = layout.arrays[array].centroid();
    let mut report = Report::default();
    let mut meter = BandMeter::new(cfg, frame, fs);
    let levels = meter.levels(truth, fs);
    let mut start = 0;
    while start + frame <= audio.frames() {
        let hop: Vec<&[f64]> = channels.iter().map(|c| &c[start..start + frame]).collect();
        let all = loc.process(stft.push(&hop));
        let obs: &ArrayObservation = all.iter().find(|o| o.array == array).expect("array");
        let span = Span::new(start, frame, fs);
        let seen = FrameTruth::of(truth, &levels, &mut meter, start, span);
        report.score(obs, &centre, &seen);
        if std::env::var("AVSEP_EVAL_VERBOSE").is_ok() {
            print_frame(obs, &centre, truth, &seen);
        }
        start += frame;
    }
    report
}

/// A localisation frame: its start and end (s) and its centre.
#[derive(Clone, Copy)]
struct Span {
    t0: f64,
    t1: f64,
    tm: f64,
}

impl Span {
    fn new(start: usize, frame: usize, fs: f64) -> Self {
        let (t0, t1) = (start as f64 / fs, (start + frame) as f64 / fs);
        Self {
            t0,
            t1,
            tm: 0.5 * (t0 + t1),
        }
    }

    /// Whether the talker exists at the frame's centre and speaks for half the frame or more.
    fn is_active(&self, s: &TruthSource) -> bool {
        s.exists_at(self.tm) && s.active_fraction(self.t0, self.t1) >= 0.5
    }
}

/// Energy of a signal's frames in the localiser's band: what the localiser can possibly hear
/// of a talker.
struct BandMeter {
    stft: Stft,
    bins: Vec<Complex>,
    frame: usize,
    /// First and last bin of the band.
    band: (usize, usize),
}

impl BandMeter {
    fn new(cfg: &LocalizerConfig, frame: usize, fs: f64) -> Self {
        Self {
            stft: Stft::new(frame),
            bins: vec![Complex::new(0.0, 0.0); frame / 2 + 1],
            frame,
            band: (
                (cfg.band_low_hz * frame as f64 / fs).ceil() as usize,
                (cfg.band_high_hz * frame as f64 / fs).floor() as usize,
            ),
        }
    }

    /// Band energy of the frame of `sig` from sample `start`.
    fn energy(&mut self, sig: &[f32], start: usize) -> f64 {
        let x: Vec<f64> = sig[start..start + self.frame]
            .iter()
            .map(|&v| f64::from(v))
            .collect();
        self.stft.forward(&x, &mut self.bins);
        let (k0, k1) = self.band;
        self.bins[k0..=k1].iter().map(|b| b.norm_sqr()).sum()
    }

    /// Each talker's mean band energy over the frames where it speaks for half the frame or
    /// more; none without a signal or such frames.
    fn levels(&mut self, truth: &Truth, fs: f64) -> Vec<Option<f64>> {
        let frame = self.frame;
        truth
            .sources
            .iter()
            .map(|s| {
                let sig = s.signal.as_ref()?;
                let (mut sum, mut n) = (0.0, 0);
                let mut start = 0;
                while start + frame <= sig.len() {
                    let (t0, t1) = (start as f64 / fs, (start + frame) as f64 / fs);
                    if s.active_fraction(t0, t1) >= 0.5 {
                        sum += self.energy(sig, start);
                        n += 1;
                    }
                    start += frame;
                }
                (n > 0).then(|| sum / n as f64)
            })
            .collect()
    }
}

/// What the truth says of one frame.
struct FrameTruth {
    span: Span,
    /// Positions of the active talkers.
    active: Vec<Vec3>,
    /// Per active talker, its band energy in the frame and its mean level (1, 1 without a
    /// signal).
    energies: Vec<(f64, f64)>,
}

impl FrameTruth {
    fn of(
        truth: &Truth,
        levels: &[Option<f64>],
        meter: &mut BandMeter,
        start: usize,
        span: Span,
    ) -> Self {
        let active: Vec<Vec3> = truth
            .sources
            .iter()
            .filter(|s| span.is_active(s))
            .filter_map(|s| s.position_at(span.tm))
            .collect();
        let energies: Vec<(f64, f64)> = truth
            .sources
            .iter()
            .zip(levels)
            .filter(|(s, _)| span.is_active(s) && s.position_at(span.tm).is_some())
            .map(|(s, level)| match (s.signal.as_ref(), level) {
                (Some(sig), Some(l)) => (meter.energy(sig, start), *l),
                _ => (1.0, 1.0),
            })
            .collect();
        Self {
            span,
            active,
            energies,
        }
    }
}

impl Report {
    /// Adds one frame's candidates, scored against the frame's truth.
    fn score(&mut self, obs: &ArrayObservation, centre: &Vec3, seen: &FrameTruth) {
        let energies = &seen.energies;
        let audible: Vec<bool> = energies.iter().map(|(e, l)| *e >= 0.1 * l).collect();
        let loudest = (0..energies.len()).max_by(|&a, &b| energies[a].0.total_cmp(&energies[b].0));
        self.frames += 1;
        self.doas += obs.doas.len();
        self.points += obs.points.len();
        if loudest.is_some() {
            self.dominant += 1;
        }
        for (i, (p, &loud)) in seen.active.iter().zip(&audible).enumerate() {
            self.active += 1;
            self.audible += usize::from(loud);
            let az = azimuth_of(&(p - centre));
            let err = obs
                .doas
                .iter()
                .map(|d| deg(angle_diff(d.azimuth, az).abs()))
                .fold(f64::INFINITY, f64::min);
            if err.is_finite() {
                self.azimuth_errors.push(err);
            }
            if err <= 5.0 {
                self.hits_5deg += 1;
                self.audible_hits_5deg += usize::from(loud);
                self.dominant_hits_5deg += usize::from(loudest == Some(i));
            }
        }
        let points: Vec<Vec3> = obs.points.iter().map(|p| p.position).collect();
        let o = ospa(&points, &seen.active, OspaParams::new(1.0, 1.0));
        let d = o.total;
        self.ospa.push(d);
        self.ospa_card.push(o.cardinality);
        if seen.active.is_empty() {
            self.activity_quiet.push(obs.activity);
        } else {
            self.ospa_speech.push(d);
            self.activity_speech.push(obs.activity);
        }
    }
}

/// Prints one frame's candidates next to the truth, for tuning (`AVSEP_EVAL_VERBOSE`).
fn print_frame(obs: &ArrayObservation, centre: &Vec3, truth: &Truth, seen: &FrameTruth) {
    let tm = seen.span.tm;
    let pts: Vec<String> = obs
        .points
        .iter()
        .map(|p| {
            format!(
                "({:.1},{:.1},{:.1})@{:.2}",
                p.position.x, p.position.y, p.position.z, p.power
            )
        })
        .collect();
    let tp: Vec<String> = seen
        .active
        .iter()
        .map(|p| format!("({:.1},{:.1},{:.1})", p.x, p.y, p.z))
        .collect();
    eprintln!("   points {pts:?} truth {tp:?}");
    let truth_az: Vec<String> = seen
        .active
        .iter()
        .map(|p| {
            let d = p - centre;
            format!(
                "{:.0}/{:.0}",
                deg(azimuth_of(&d)),
                deg(d.z.atan2(d.x.hypot(d.y)))
            )
        })
        .collect();
    let found: Vec<String> = obs
        .doas
        .iter()
        .map(|d| {
            format!(
                "{:.0}/{:.0}@{:.2}",
                deg(d.azimuth),
                deg(d.elevation),
                d.power
            )
        })
        .collect();
    let level_db: Vec<String> = seen
        .energies
        .iter()
        .map(|(e, l)| format!("{:.0}", 10.0 * (e / l).log10()))
        .collect();
    let idle: Vec<String> = truth
        .sources
        .iter()
        .filter(|s| !seen.span.is_active(s))
        .filter_map(|s| s.position_at(tm))
        .map(|p| format!("{:.0}", deg(azimuth_of(&(p - centre)))))
        .collect();
    eprintln!(
        "t {tm:5.2} act {:.2} truth {truth_az:?} found {found:?} level_db {level_db:?} idle {idle:?}",
        obs.activity
    );
}
