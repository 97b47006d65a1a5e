//! Geodesic spheres: icosahedron subdivision, as in ODAS's hierarchical scan.

use std::collections::HashMap;

use crate::geometry::Vec3;

/// Unit directions of a subdivided icosahedron and their mesh neighbours.
pub(crate) struct GeodesicSphere {
    /// Unit vectors; the points of level L are the first points of level L + 1.
    pub points: Vec<Vec3>,
    /// Indices of the points sharing a mesh edge with each point.
    pub neighbours: Vec<Vec<usize>>,
}

impl GeodesicSphere {
    /// The sphere of subdivision `level`: 10 * 4^level + 2 points.
    pub fn new(level: u32) -> Self {
        let t = (1.0 + 5f64.sqrt()) / 2.0;
        let mut points: Vec<Vec3> = [
            (-1.0, t, 0.0),
            (1.0, t, 0.0),
            (-1.0, -t, 0.0),
            (1.0, -t, 0.0),
            (0.0, -1.0, t),
            (0.0, 1.0, t),
            (0.0, -1.0, -t),
            (0.0, 1.0, -t),
            (t, 0.0, -1.0),
            (t, 0.0, 1.0),
            (-t, 0.0, -1.0),
            (-t, 0.0, 1.0),
        ]
        .iter()
        .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
        .collect();
        let mut faces: Vec<[usize; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..level {
            let mut midpoints: HashMap<(usize, usize), usize> = HashMap::new();
            let mut midpoint = |a: usize, b: usize, points: &mut Vec<Vec3>| -> usize {
                let key = (a.min(b), a.max(b));
                *midpoints.entry(key).or_insert_with(|| {
                    points.push((points[a] + points[b]).normalize());
                    points.len() - 1
                })
            };
            let mut next = Vec::with_capacity(faces.len() * 4);
            for &[a, b, c] in &faces {
                let ab = midpoint(a, b, &mut points);
                let bc = midpoint(b, c, &mut points);
                let ca = midpoint(c, a, &mut points);
                next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
            }
            faces = next;
        }
        let mut neighbours = vec![Vec::new(); points.len()];
        for f in &faces {
            for i in 0..3 {
                let (a, b) = (f[i], f[(i + 1) % 3]);
                if !neighbours[a].contains(&b) {
                    neighbours[a].push(b);
                }
                if !neighbours[b].contains(&a) {
                    neighbours[b].push(a);
                }
            }
        }
        Self { points, neighbours }
    }

    /// Mean angle (radians) between neighbouring points.
    pub fn spacing(&self) -> f64 {
        let (mut sum, mut n) = (0.0, 0usize);
        for (i, nb) in self.neighbours.iter().enumerate() {
            for &j in nb {
                sum += self.points[i].dot(&self.points[j]).clamp(-1.0, 1.0).acos();
                n += 1;
            }
        }
        sum / n.max(1) as f64
    }

    /// Index of the point nearest to unit vector `d`, by greedy descent from `start` (exact on a
    /// geodesic mesh, whose triangulation is Delaunay).
    pub fn nearest(&self, d: &Vec3, start: usize) -> usize {
        let mut best = start;
        let mut best_dot = self.points[best].dot(d);
        loop {
            let mut moved = false;
            for &j in &self.neighbours[best] {
                let v = self.points[j].dot(d);
                if v > best_dot {
                    best_dot = v;
                    best = j;
                    moved = true;
                }
            }
            if !moved {
                return best;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_counts_follow_subdivision() {
        for level in 0..=4 {
            let s = GeodesicSphere::new(level);
            assert_eq!(s.points.len(), 10 * 4usize.pow(level) + 2);
            assert!(s.points.iter().all(|p| (p.norm() - 1.0).abs() < 1e-12));
            // Euler: every vertex has 5 or 6 neighbours.
            assert!(s.neighbours.iter().all(|n| n.len() == 5 || n.len() == 6));
        }
        let s2 = GeodesicSphere::new(2);
        let s4 = GeodesicSphere::new(4);
        assert!(
            (s2.spacing().to_degrees() - 15.9).abs() < 1.5,
            "{}",
            s2.spacing().to_degrees()
        );
        assert!(
            (s4.spacing().to_degrees() - 4.0).abs() < 0.5,
            "{}",
            s4.spacing().to_degrees()
        );
        // Coarse points are a prefix of the fine ones.
        for i in 0..s2.points.len() {
            assert!((s2.points[i] - s4.points[i]).norm() < 1e-12);
        }
    }

    #[test]
    fn greedy_nearest_matches_brute_force() {
        let s = GeodesicSphere::new(3);
        let fine = GeodesicSphere::new(5);
        for d in fine.points.iter().step_by(7) {
            let brute = (0..s.points.len())
                .max_by(|&i, &j| s.points[i].dot(d).total_cmp(&s.points[j].dot(d)))
                .unwrap();
            let greedy = s.nearest(d, 0);
            assert!((s.points[greedy].dot(d) - s.points[brute].dot(d)).abs() < 1e-12);
        }
    }
}
