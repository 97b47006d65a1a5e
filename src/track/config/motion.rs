//! The motion model's settings.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Dynamic model of a track.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema, Default)]
#[serde(rename_all = "snake_case")]
pub enum MotionKind {
    /// Langevin model of the paper (spec 003 eq. 14-15): mean-reverting velocity.
    #[default]
    Langevin,
    /// Nearly constant velocity (piecewise-constant white acceleration).
    ConstantVelocity,
}

/// Motion model parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct MotionConfig {
    /// `langevin` (default, the paper's model) or `constant_velocity`.
    pub model: MotionKind,
    /// Langevin: velocity decay rate beta (1/s; paper: 10); with `gait`, a standing track's.
    /// 2/s keeps a velocity for about half a second, enough to carry two tracks through a
    /// crossing more often than the paper's 0.1 s (see `sigma_m_per_s` for the measurements),
    /// measured before `gait` gave walkers a slower decay. Re-measured with the gait (the
    /// default), 1 against 2, full pipeline, 3-D MOTA / HOTA: `two-arrays` seeds 1-12 59.6 /
    /// 44.0 against 58.8 / 43.0 %, seeds 13-24 66.8 / 48.4 against 65.5 / 47.2 %, recorded
    /// speech seeds 1-12 60.1 / 45.0 against 58.8 / 43.9 %; uca8 three talkers seeds 1-18
    /// 95.1 / 82.8 against 94.8 / 83.0 %, 19-30 96.9 / 83.8 against 96.6 / 84.2 %;
    /// paper-linear6 seeds 1-48 98.1 / 80.1 against 98.0 / 80.5 %, 49-72 98.3 / 78.9 against
    /// 98.4 / 79.2 %; SI-SDRi within 0.2 dB everywhere. Audio-only uca8, whose tracks have no
    /// gait: 36.0 against 40.9 % MOTA (without the gait 0.5 gave 32.5 %). The faster decay
    /// stays: the slower one overshoots standing talkers (HOTA) and lets direction-only tracks
    /// drift.
    pub beta_per_s: f64,
    /// Langevin: steady-state RMS velocity nu (m/s; paper: 1).
    pub nu_m_per_s: f64,
    /// Langevin: per-axis velocity noise sigma (x, y, z; paper: [1.2, 1.2, 0.2], for people
    /// walking about). Over times beyond 1 / beta the position spreads by 2 nu^2 sigma^2 / beta
    /// m^2/s: the paper's values let an unobserved track spread by 0.54 m in a second, wide
    /// enough for a silent talker whose face is turned away to be pulled onto a reverberant
    /// image of another talker 30 degrees off, and to let the unobservable range of a
    /// direction-only track drift. With beta = 2/s, [0.27, 0.27, 0.05] spreads by 0.27 m in a
    /// second and still follows walkers at 0.5-0.7 m/s; it measured better than the paper's
    /// values on `paper-linear6`, `uca8` (2 and 3 talkers) and `two-arrays`, seeds 1-10
    /// (OSPA(2), MOTA, label counts and switches, audio-visual and audio-only).
    pub sigma_m_per_s: [f64; 3],
    /// Langevin: give each track a gait, standing or walking (`track::gait`, an interacting
    /// multiple model): a standing track's velocity decays at `beta_per_s`, a walking one's at
    /// `walking_beta_per_s`, and the measurements tell which it does. With `false` every track
    /// decays at `beta_per_s`. One decay served walkers or standers: 0.5/s for every track
    /// (full pipeline, 3-D MOTA / HOTA) took `two-arrays` seeds 1-12 from 54.6 / 40.3 % to
    /// 58.6 / 43.8 % but `paper-linear6` seeds 1-48 from 80.5 to 79.4 % HOTA (its tracks
    /// overshot talkers who stopped) and audio-only uca8 from 40.9 to 32.5 % MOTA. The gait
    /// (default) against `false`: `two-arrays` 58.8 / 43.0 %, seeds 13-24 65.5 / 47.2 against
    /// 61.2 / 43.1 %, recorded speech seeds 1-6 61.3 / 41.2 against 57.6 / 39.1 %, 7-12 56.2 /
    /// 46.5 against 57.6 / 44.7 % (one scene's unseen walker got a second label); uca8 three
    /// talkers seeds 1-18 94.8 / 83.0 against 93.5 / 82.4 %, recorded 1-12 93.2 / 81.2 against
    /// 92.7 / 81.0 %; `paper-linear6` 98.0 / 80.5 against 97.9 / 80.5 %. SI-SDRi moves within
    /// the scenes' spread: `two-arrays` +4.17 against +4.21 dB, seeds 13-24 +5.33 against
    /// +5.26, uca8 +9.42 against +9.37, `paper-linear6` +7.88 against +7.87.
    pub gait: bool,
    /// Langevin with `gait`: velocity decay rate (1/s) of a walking track: it keeps a
    /// walker's velocity for about 2 s. 0.25: `two-arrays` seeds 1-12 58.7 / 43.1 % MOTA /
    /// HOTA against 58.8 / 43.0, `paper-linear6` seeds 1-24 HOTA 82.0 against 82.5 %.
    pub walking_beta_per_s: f64,
    /// Langevin with `gait`: per-axis velocity noise factors of a walking track (m/s). Its
    /// steady-state speed (times `nu_m_per_s`) should exceed a standing track's. With the
    /// standing mode's [0.27, 0.27, 0.05] the walking mode, whose velocity persists, predicted
    /// a still talker better than the standing one, whose velocity is redrawn every half
    /// second: standing tracks read as walking (0.75 on `paper-linear6` seed 2) and overshot
    /// talkers who stopped (HOTA 79.8 against 80.5 % on seeds 1-48). 0.4 and 0.6:
    /// `two-arrays` seeds 1-12 59.1 / 42.9 and 58.7 / 42.8 % MOTA / HOTA, `paper-linear6`
    /// seeds 1-24 HOTA 82.3 and 82.6 %.
    pub walking_sigma_m_per_s: [f64; 3],
    /// With `gait`: how long (s) after its last camera detection (or any sensor's that is not
    /// audio) a track keeps its gait; a track no camera saw within it stands. From audio
    /// directions alone a track's range is unobserved, and a walking mode keeps the noise
    /// that moved it: the gait on every track took audio-only uca8 seeds 1-18 from 40.9 to
    /// 38.2 % MOTA (-0.42 dB SI-SDRi) and recorded uca8 seeds 1-12 from 92.7 to 92.3 % (1.139
    /// to 1.194 streams per talker). 2 and 1000: `two-arrays` seeds 1-12 56.7 and 58.8 % MOTA,
    /// recorded uca8 93.3 and 92.3 %.
    pub gait_camera_memory_s: f64,
    /// Mean time (s) a walk lasts (the gait chain's rate of stopping). 2 with
    /// `mean_stand_s` 5: `two-arrays` seeds 1-12 58.8 / 43.0 % MOTA / HOTA, `paper-linear6`
    /// seeds 1-24 HOTA 82.5 %, as with the defaults.
    pub mean_walk_s: f64,
    /// Mean time (s) a stand lasts (its rate of starting to walk).
    pub mean_stand_s: f64,
    /// Constant velocity: per-axis white-acceleration standard deviation (m/s^2).
    pub accel_std_m_per_s2: [f64; 3],
}

impl Default for MotionConfig {
    fn default() -> Self {
        Self {
            model: MotionKind::Langevin,
            beta_per_s: 2.0,
            nu_m_per_s: 1.0,
            sigma_m_per_s: [0.27, 0.27, 0.05],
            gait: true,
            walking_beta_per_s: 0.5,
            walking_sigma_m_per_s: [0.5, 0.5, 0.05],
            gait_camera_memory_s: 5.0,
            mean_walk_s: 3.0,
            mean_stand_s: 10.0,
            accel_std_m_per_s2: [2.0, 2.0, 0.5],
        }
    }
}
