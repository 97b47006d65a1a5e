//! Per-bin noise floor by minimum statistics, for weighting the GCC towards bins where the
//! sources stand above the noise.

/// The minimum over the last frames of each band bin's power (mean over the array's channels).
#[derive(Debug, Clone)]
pub(crate) struct BinNoiseFloor {
    bins: usize,
    window: usize,
    history: Vec<f64>,
    next: usize,
    filled: usize,
    floor: Vec<f64>,
}

impl BinNoiseFloor {
    /// A floor over `window` frames of `bins` bins.
    pub fn new(bins: usize, window: usize) -> Self {
        Self {
            bins,
            window,
            history: vec![0.0; bins * window],
            next: 0,
            filled: 0,
            floor: vec![0.0; bins],
        }
    }

    /// Adds one (non-silent) frame's bin powers and returns the floor including it.
    pub fn update(&mut self, power: &[f64]) -> &[f64] {
        let slot = self.next * self.bins;
        self.history[slot..slot + self.bins].copy_from_slice(power);
        self.next = (self.next + 1) % self.window;
        self.filled = (self.filled + 1).min(self.window);
        self.floor.copy_from_slice(power);
        for frame in self.history.chunks_exact(self.bins).take(self.filled) {
            for (f, p) in self.floor.iter_mut().zip(frame) {
                *f = f.min(*p);
            }
        }
        &self.floor
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_is_the_running_minimum_per_bin() {
        let mut f = BinNoiseFloor::new(2, 3);
        assert_eq!(f.update(&[4.0, 1.0]), &[4.0, 1.0]);
        assert_eq!(f.update(&[2.0, 5.0]), &[2.0, 1.0]);
        assert_eq!(f.update(&[3.0, 6.0]), &[2.0, 1.0]);
        // The frame with 1.0 in bin 1 leaves the window.
        assert_eq!(f.update(&[9.0, 7.0]), &[2.0, 5.0]);
    }
}
