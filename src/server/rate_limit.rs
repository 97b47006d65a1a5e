//! A token bucket: at most `rate` events a second on average, `burst` at once.

use std::time::Instant;

/// Admits events at a bounded rate; each refused one is counted until the next admitted one.
#[derive(Debug)]
pub struct TokenBucket {
    rate: f64,
    burst: f64,
    tokens: f64,
    last: Option<Instant>,
    refused: u64,
}

impl TokenBucket {
    /// A full bucket: `burst` events pass at once, then `rate` a second.
    pub fn new(rate: f64, burst: f64) -> Self {
        Self {
            rate: rate.max(0.0),
            burst: burst.max(1.0),
            tokens: burst.max(1.0),
            last: None,
            refused: 0,
        }
    }

    /// Whether an event at `now` passes. When it does, the count of events refused since the
    /// last one that passed is returned (and reset), so the caller can say what it held back.
    pub fn admit(&mut self, now: Instant) -> Option<u64> {
        if let Some(last) = self.last {
            let dt = now.saturating_duration_since(last).as_secs_f64();
            self.tokens = (self.tokens + dt * self.rate).min(self.burst);
        }
        self.last = Some(now);
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            Some(std::mem::take(&mut self.refused))
        } else {
            self.refused += 1;
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn passes_a_burst_then_the_rate_and_counts_what_it_held_back() {
        let t0 = Instant::now();
        let mut b = TokenBucket::new(10.0, 3.0);
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        assert_eq!(
            (0..5).map(|_| b.admit(at(0))).collect::<Vec<_>>(),
            [Some(0), Some(0), Some(0), None, None]
        );
        // 50 ms refill half a token: still held back.
        assert_eq!(b.admit(at(50)), None);
        // 100 ms after the burst one token is back; the three held back are reported.
        assert_eq!(b.admit(at(100)), Some(3));
        assert_eq!(b.admit(at(100)), None);
        // A long pause refills only up to the burst.
        let passed = (0..10).filter(|_| b.admit(at(60_000)).is_some()).count();
        assert_eq!(passed, 3);
    }

    #[test]
    fn a_zero_rate_passes_the_burst_only() {
        let t0 = Instant::now();
        let mut b = TokenBucket::new(0.0, 2.0);
        let passed = (0..100u64)
            .filter(|&i| b.admit(t0 + Duration::from_secs(i)).is_some())
            .count();
        assert_eq!(passed, 2);
    }
}
