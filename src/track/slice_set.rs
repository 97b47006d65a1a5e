//! An interning set of short integer slices, stored in one arena.
//!
//! The GLMB update deduplicates Gibbs samples, keys its table of single-object updates by
//! (track, measurement index per sensor) and merges identical hypotheses. All three are sets of
//! short integer slices looked up thousands of times per step, so they share this open-addressing
//! table with a cheap multiplicative hash and no per-key allocation.

/// A set of slices; each distinct slice gets a dense id in insertion order.
#[derive(Debug, Clone, Default)]
pub(crate) struct SliceSet<T> {
    arena: Vec<T>,
    spans: Vec<(u32, u32)>,
    hashes: Vec<u64>,
    table: Vec<u32>,
}

const EMPTY: u32 = u32::MAX;

fn hash_slice<T: Copy + Into<u64>>(key: &[T]) -> u64 {
    // FxHash-style mixing: fast, and good enough for small dense integers.
    let mut h: u64 = key.len() as u64;
    for &v in key {
        h = (h.rotate_left(5) ^ v.into()).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    h ^ (h >> 29)
}

impl<T: Copy + Eq + Into<u64>> SliceSet<T> {
    /// Removes every slice, keeping the allocations.
    pub fn clear(&mut self) {
        self.arena.clear();
        self.spans.clear();
        self.hashes.clear();
        self.table.iter_mut().for_each(|s| *s = EMPTY);
    }

    /// Number of distinct slices.
    pub fn len(&self) -> usize {
        self.spans.len()
    }

    /// The slice with id `i`.
    pub fn get(&self, i: usize) -> &[T] {
        let (s, l) = self.spans[i];
        &self.arena[s as usize..(s + l) as usize]
    }

    /// The id of `key`, inserting it if new; the flag says whether it was new.
    pub fn insert(&mut self, key: &[T]) -> (usize, bool) {
        if self.table.is_empty() {
            self.table = vec![EMPTY; 64];
        }
        let h = hash_slice(key);
        let mask = self.table.len() - 1;
        let mut slot = (h as usize) & mask;
        loop {
            let id = self.table[slot];
            if id == EMPTY {
                break;
            }
            if self.hashes[id as usize] == h && self.get(id as usize) == key {
                return (id as usize, false);
            }
            slot = (slot + 1) & mask;
        }
        let id = self.spans.len();
        self.spans.push((self.arena.len() as u32, key.len() as u32));
        self.arena.extend_from_slice(key);
        self.hashes.push(h);
        self.table[slot] = id as u32;
        if 2 * self.spans.len() > self.table.len() {
            self.grow();
        }
        (id, true)
    }

    fn grow(&mut self) {
        let size = self.table.len() * 2;
        self.table.clear();
        self.table.resize(size, EMPTY);
        let mask = size - 1;
        for (id, &h) in self.hashes.iter().enumerate() {
            let mut slot = (h as usize) & mask;
            while self.table[slot] != EMPTY {
                slot = (slot + 1) & mask;
            }
            self.table[slot] = id as u32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interns_distinct_slices_in_order() {
        let mut s = SliceSet::<u32>::default();
        // (i mod 300, i mod 7) repeats only with period 2100: 1000 distinct keys.
        for i in 0..1000u32 {
            assert_eq!(s.insert(&[i % 300, i % 7]), (i as usize, true));
        }
        for i in 0..1000u32 {
            assert_eq!(s.insert(&[i % 300, i % 7]), (i as usize, false));
        }
        assert_eq!(s.len(), 1000);
        assert_eq!(s.get(5), &[5, 5]);
        assert!(s.insert(&[]).1);
        assert!(!s.insert(&[]).1);
        s.clear();
        assert_eq!(s.len(), 0);
        assert_eq!(s.insert(&[5, 5]), (0, true));
    }
}
