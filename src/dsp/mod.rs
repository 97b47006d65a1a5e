//! Signal-processing building blocks shared by the localiser and the separator: windows, the
//! short-time Fourier transform and its perfect-reconstruction inverse, and a single-voice
//! pitch estimator (YIN) for oracle runs.

mod spectrum;
mod stft;
mod window;
mod yin;

pub use spectrum::MultiSpectrum;
pub use stft::{FrameGeometry, Istft, Stft, StreamingStft};
pub use window::hann_periodic;
pub use yin::{VoicePitch, Yin};

/// Complex sample type used for spectra.
pub type Complex = num_complex::Complex<f64>;

/// The inner product a^H b (`a` conjugated) over the shorter of the two slices: a beamformer's
/// output for a snapshot, or its response to a steering vector.
#[inline]
pub fn inner(a: &[Complex], b: &[Complex]) -> Complex {
    a.iter().zip(b).map(|(x, y)| x.conj() * y).sum()
}
