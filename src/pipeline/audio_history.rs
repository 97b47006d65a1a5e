//! Recent multichannel audio indexed by absolute sample number (session time).

use std::collections::VecDeque;

/// Per-channel history of the last samples received, addressed by absolute sample index.
///
/// Indices before the first sample (negative) read as zeros: that is the STFT prepad.
#[derive(Debug, Clone)]
pub struct AudioHistory {
    channels: Vec<VecDeque<f64>>,
    /// Absolute index of the oldest retained sample.
    start: u64,
    /// Absolute index one past the newest sample.
    end: u64,
    capacity: usize,
}

impl AudioHistory {
    /// History of `channels` channels keeping at least `capacity` samples.
    pub fn new(channels: usize, capacity: usize) -> Self {
        Self {
            channels: vec![VecDeque::with_capacity(capacity + 4096); channels],
            start: 0,
            end: 0,
            capacity,
        }
    }

    /// Keeps at least `capacity` samples from now on (the oldest go if it shrinks).
    pub fn set_capacity(&mut self, capacity: usize) {
        self.capacity = capacity;
        self.trim();
    }

    /// Absolute index one past the newest sample.
    pub fn end(&self) -> u64 {
        self.end
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.channels.len()
    }

    /// Appends interleaved samples (already validated: finite, right channel count).
    pub fn append_interleaved(&mut self, samples: &[f32]) {
        let n = self.channels.len();
        if n == 0 {
            return;
        }
        for frame in samples.chunks_exact(n) {
            for (ch, &s) in self.channels.iter_mut().zip(frame) {
                ch.push_back(f64::from(s));
            }
        }
        self.end += (samples.len() / n) as u64;
        self.trim();
    }

    /// Appends `count` samples of silence to every channel (to bridge a gap in the input).
    pub fn append_silence(&mut self, count: usize) {
        if count >= self.capacity {
            // Only the last `capacity` samples would survive the trim: the rest is never built,
            // so a long gap costs no more memory than the history holds.
            for ch in &mut self.channels {
                ch.clear();
                ch.resize(self.capacity, 0.0);
            }
            self.end += count as u64;
            self.start = self.end - self.capacity as u64;
            return;
        }
        for ch in &mut self.channels {
            ch.extend(std::iter::repeat_n(0.0, count));
        }
        self.end += count as u64;
        self.trim();
    }

    fn trim(&mut self) {
        let len = (self.end - self.start) as usize;
        if len > self.capacity {
            let drop = len - self.capacity;
            for ch in &mut self.channels {
                ch.drain(..drop);
            }
            self.start += drop as u64;
        }
    }

    /// Appends samples `[from, to)` of every channel to `out`, interleaved (the history holds
    /// what came in as f32, or silence, so the conversion is exact).
    pub fn read_interleaved(&self, from: u64, to: u64, out: &mut Vec<f32>) -> Result<(), String> {
        if to > self.end || from < self.start {
            return Err(format!(
                "samples {from}..{to} requested but {}..{} held",
                self.start, self.end
            ));
        }
        let (a, b) = ((from - self.start) as usize, (to - self.start) as usize);
        out.reserve((b.saturating_sub(a)) * self.channels.len());
        for i in a..b {
            out.extend(self.channels.iter().map(|ch| ch[i] as f32));
        }
        Ok(())
    }

    /// Copies samples `[from, from + out.len())` of channel `ch` into `out`. Indices before 0 read as
    /// zeros; indices not (or no longer) held are an error (the caller's scheduling is wrong).
    pub fn read(&self, ch: usize, from: i64, out: &mut [f64]) -> Result<(), String> {
        let to = from + out.len() as i64;
        if to > self.end as i64 {
            return Err(format!(
                "samples up to {to} requested but only {} received",
                self.end
            ));
        }
        let data = &self.channels[ch];
        // Before sample 0: the zero prepad; the rest is two contiguous runs of the ring.
        let zeros = ((-from).max(0) as usize).min(out.len());
        out[..zeros].fill(0.0);
        if zeros == out.len() {
            return Ok(());
        }
        let first = (from + zeros as i64) as u64;
        if first < self.start {
            return Err(format!(
                "sample {first} already discarded (oldest kept is {})",
                self.start
            ));
        }
        let offset = (first - self.start) as usize;
        let rest = &mut out[zeros..];
        let (a, b) = data.as_slices();
        let n = rest.len();
        if offset >= a.len() {
            rest.copy_from_slice(&b[offset - a.len()..offset - a.len() + n]);
        } else {
            let in_a = (a.len() - offset).min(n);
            rest[..in_a].copy_from_slice(&a[offset..offset + in_a]);
            rest[in_a..].copy_from_slice(&b[..n - in_a]);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_by_absolute_index_with_zero_prepad() {
        let mut h = AudioHistory::new(2, 8);
        h.append_interleaved(&[1.0, -1.0, 2.0, -2.0, 3.0, -3.0]);
        let mut out = [9.0; 4];
        h.read(1, -1, &mut out).unwrap();
        assert_eq!(out, [0.0, -1.0, -2.0, -3.0]);
        assert!(h.read(0, 1, &mut out).is_err(), "beyond the end");
        h.append_silence(10);
        assert_eq!(h.end(), 13);
        assert!(h.read(0, 0, &mut [0.0; 2]).is_err(), "discarded");
        let mut tail = [1.0; 3];
        h.read(0, 10, &mut tail).unwrap();
        assert_eq!(tail, [0.0; 3]);
    }

    #[test]
    fn a_gap_longer_than_the_history_costs_only_the_history() {
        // A gap of a trillion samples on 100 channels would be 800 TB if built; it keeps the
        // last `capacity` samples of silence, exactly as a short gap trimmed would.
        let mut h = AudioHistory::new(100, 16);
        h.append_interleaved(&[1.0; 100 * 4]);
        let gap = 1_000_000_000_000usize;
        h.append_silence(gap);
        assert_eq!(h.end(), 4 + gap as u64);
        assert!(h.channels.iter().all(|c| c.len() == 16));
        let mut out = [1.0; 16];
        h.read(99, h.end() as i64 - 16, &mut out).unwrap();
        assert_eq!(out, [0.0; 16]);
        assert!(
            h.read(0, h.end() as i64 - 17, &mut out).is_err(),
            "discarded"
        );
        // New samples follow the silence.
        h.append_interleaved(&[2.0; 100]);
        let mut last = [0.0; 2];
        h.read(0, h.end() as i64 - 2, &mut last).unwrap();
        assert_eq!(last, [0.0, 2.0]);
        // The same as a gap of exactly the capacity and one just short of it.
        for gap in [15, 16] {
            let mut h = AudioHistory::new(1, 16);
            h.append_interleaved(&[1.0; 4]);
            h.append_silence(gap);
            let mut out = [9.0; 16];
            h.read(0, h.end() as i64 - 16, &mut out).unwrap();
            let ones = 16usize.saturating_sub(gap);
            assert!(out[..ones].iter().all(|&v| v == 1.0), "gap {gap}: {out:?}");
            assert!(out[ones..].iter().all(|&v| v == 0.0), "gap {gap}: {out:?}");
        }
    }

    #[test]
    fn reads_interleaved_ranges() {
        let mut h = AudioHistory::new(2, 3);
        h.append_interleaved(&[1.0, -1.0, 2.0, -2.0, 3.0, -3.0, 4.0, -4.0]);
        let mut out = vec![9.0];
        h.read_interleaved(2, 4, &mut out).unwrap();
        assert_eq!(out, [9.0, 3.0, -3.0, 4.0, -4.0]);
        assert!(h.read_interleaved(0, 2, &mut out).is_err(), "discarded");
        assert!(
            h.read_interleaved(3, 5, &mut out).is_err(),
            "beyond the end"
        );
    }

    #[test]
    fn reads_across_the_ring_wrap() {
        // Appending past the capacity drains the front, so the deque's storage wraps around.
        let mut h = AudioHistory::new(1, 6);
        for i in 0..40 {
            h.append_interleaved(&[i as f32]);
            let from = i64::from(i) - 5;
            let mut out = [f64::NAN; 6];
            h.read(0, from, &mut out).unwrap();
            let want: Vec<f64> = (from..=i64::from(i)).map(|x| x.max(-1) as f64).collect();
            let want: Vec<f64> = want
                .iter()
                .map(|&x| if x < 0.0 { 0.0 } else { x })
                .collect();
            assert_eq!(out.to_vec(), want, "reading {from}..={i}");
        }
    }
}
