//! Dense Cholesky factorisation of the symmetric positive (semi-)definite Gram systems of BSS
//! Eval, with diagonal loading so that silent or linearly dependent references stay solvable.

/// A factored `n x n` system `(A + delta I) = L L^T`, `L` stored row by row (lower triangle).
#[derive(Debug, Clone)]
pub struct Cholesky {
    n: usize,
    l: Vec<f64>,
}

/// Relative diagonal loading: small enough to leave well-posed projections unchanged to about
/// 100 dB, large enough to keep rank-deficient Gram matrices (silence, band-limited signals)
/// factorable.
const LOADING: f64 = 1e-10;

fn dot(a: &[f64], b: &[f64]) -> f64 {
    // Four partial sums let the compiler keep several multiply-adds in flight.
    let mut acc = [0.0f64; 4];
    let mut ca = a.chunks_exact(4);
    let mut cb = b.chunks_exact(4);
    for (x, y) in (&mut ca).zip(&mut cb) {
        acc[0] += x[0] * y[0];
        acc[1] += x[1] * y[1];
        acc[2] += x[2] * y[2];
        acc[3] += x[3] * y[3];
    }
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

impl Cholesky {
    /// Factors the symmetric matrix `a` (row-major, `n x n`; only the lower triangle is read).
    pub fn new(mut a: Vec<f64>, n: usize) -> Self {
        debug_assert_eq!(a.len(), n * n);
        let trace: f64 = (0..n).map(|i| a[i * n + i].abs()).sum();
        let delta = LOADING * trace / n.max(1) as f64 + f64::MIN_POSITIVE;
        for j in 0..n {
            let (done, rest) = a.split_at_mut(j * n);
            let row_j = &mut rest[..n];
            for k in 0..j {
                let row_k = &done[k * n..k * n + k + 1];
                let s = row_j[k] - dot(&row_j[..k], &row_k[..k]);
                row_j[k] = s / row_k[k];
            }
            let d = row_j[j] + delta - dot(&row_j[..j], &row_j[..j]);
            // Rounding can leave a dependent direction slightly negative: pin it at the loading.
            row_j[j] = d.max(delta).sqrt();
            for v in &mut row_j[j + 1..] {
                *v = 0.0;
            }
        }
        Self { n, l: a }
    }

    /// Solves `(A + delta I) x = b`.
    pub fn solve(&self, b: &[f64]) -> Vec<f64> {
        let n = self.n;
        let mut y = b.to_vec();
        for i in 0..n {
            let row = &self.l[i * n..i * n + i + 1];
            y[i] = (y[i] - dot(&row[..i], &y[..i])) / row[i];
        }
        for i in (0..n).rev() {
            let below: f64 = (i + 1..n).map(|k| self.l[k * n + i] * y[k]).sum();
            y[i] = (y[i] - below) / self.l[i * n + i];
        }
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_known_system() {
        let a = vec![4.0, 2.0, 0.6, 2.0, 5.0, 1.0, 0.6, 1.0, 3.0];
        let x = [1.0, -2.0, 0.5];
        let b: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| a[i * 3 + j] * x[j]).sum())
            .collect();
        let c = Cholesky::new(a, 3);
        let got = c.solve(&b);
        for (g, w) in got.iter().zip(&x) {
            assert!((g - w).abs() < 1e-8, "{got:?}");
        }
    }

    #[test]
    fn survives_a_singular_matrix() {
        // Rank one: [1 1; 1 1]. The loaded solution of b in the range is finite and consistent.
        let c = Cholesky::new(vec![1.0, 1.0, 1.0, 1.0], 2);
        let x = c.solve(&[2.0, 2.0]);
        assert!(x.iter().all(|v| v.is_finite()));
        assert!((x[0] + x[1] - 2.0).abs() < 1e-6, "{x:?}");
        let z = Cholesky::new(vec![0.0; 4], 2).solve(&[0.0, 0.0]);
        assert_eq!(z, vec![0.0, 0.0]);
    }
}
