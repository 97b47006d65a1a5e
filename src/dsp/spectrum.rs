//! Multichannel one-sided spectra.

use super::Complex;

/// One STFT frame of several channels: `bins` one-sided bins per channel, channel-major.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiSpectrum {
    bins: usize,
    channels: usize,
    data: Vec<Complex>,
}

impl MultiSpectrum {
    /// All-zero spectra.
    pub fn zeros(channels: usize, bins: usize) -> Self {
        Self {
            bins,
            channels,
            data: vec![Complex::new(0.0, 0.0); bins * channels],
        }
    }

    /// Number of one-sided frequency bins per channel.
    pub fn bins(&self) -> usize {
        self.bins
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Bins of channel `ch`.
    pub fn channel(&self, ch: usize) -> &[Complex] {
        &self.data[ch * self.bins..(ch + 1) * self.bins]
    }

    /// Mutable bins of channel `ch`.
    pub fn channel_mut(&mut self, ch: usize) -> &mut [Complex] {
        &mut self.data[ch * self.bins..(ch + 1) * self.bins]
    }

    /// Value of channel `ch` at bin `k`.
    pub fn at(&self, ch: usize, k: usize) -> Complex {
        self.data[ch * self.bins + k]
    }

    /// Copies bin `k` of every channel (the array snapshot Y(k)) into `out`.
    pub fn snapshot_into(&self, k: usize, out: &mut [Complex]) {
        for (ch, o) in out.iter_mut().enumerate().take(self.channels) {
            *o = self.data[ch * self.bins + k];
        }
    }

    /// The spectra of a subset of channels, in the given order.
    pub fn select(&self, channels: &[usize]) -> Self {
        let mut out = Self::zeros(channels.len(), self.bins);
        for (i, &ch) in channels.iter().enumerate() {
            out.channel_mut(i).copy_from_slice(self.channel(ch));
        }
        out
    }
}
