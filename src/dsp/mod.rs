//! Signal-processing building blocks shared by the localiser and the separator: windows, the
//! short-time Fourier transform and its perfect-reconstruction inverse.

mod spectrum;
mod stft;
mod window;

pub use spectrum::MultiSpectrum;
pub use stft::{FrameGeometry, Istft, Stft, StreamingStft};
pub use window::hann_periodic;

/// Complex sample type used for spectra.
pub type Complex = num_complex::Complex<f64>;
