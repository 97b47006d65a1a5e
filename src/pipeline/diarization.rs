//! Who spoke when: speech segments of each track label, from its `speaking` probability,
//! written as RTTM.

use std::collections::BTreeMap;

use crate::label::Label;

/// One speech segment of one label.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// The speaking track.
    pub label: Label,
    /// Start time (s).
    pub start: f64,
    /// Duration (s).
    pub duration: f64,
}

/// Builds segments from per-step speaking probabilities with hysteresis: a segment opens when
/// `speaking >= on` and closes after it stays below `off` for `hold_s` seconds.
#[derive(Debug, Clone)]
pub struct Diarizer {
    on: f64,
    off: f64,
    hold_s: f64,
    open: BTreeMap<Label, Open>,
    done: Vec<Segment>,
}

#[derive(Debug, Clone, Copy)]
struct Open {
    start: f64,
    last_speaking_end: f64,
}

impl Diarizer {
    /// A diarizer with the given thresholds and hold time.
    pub fn new(on: f64, off: f64, hold_s: f64) -> Self {
        Self {
            on,
            off,
            hold_s,
            open: BTreeMap::new(),
            done: Vec::new(),
        }
    }

    /// Feeds one tracker step covering `[t0, t1)` with each present label's speaking probability.
    pub fn push(&mut self, t0: f64, t1: f64, speaking: &[(Label, f64)]) {
        for &(label, p) in speaking {
            match self.open.get_mut(&label) {
                Some(o) if p >= self.off => o.last_speaking_end = t1,
                Some(_) => {}
                None if p >= self.on => {
                    self.open.insert(
                        label,
                        Open {
                            start: t0,
                            last_speaking_end: t1,
                        },
                    );
                }
                None => {}
            }
        }
        let present: Vec<Label> = speaking.iter().map(|s| s.0).collect();
        let closing: Vec<Label> = self
            .open
            .iter()
            .filter(|(l, o)| !present.contains(l) || t1 - o.last_speaking_end >= self.hold_s)
            .map(|(l, _)| *l)
            .collect();
        for l in closing {
            if let Some(o) = self.open.remove(&l) {
                self.close(l, o);
            }
        }
    }

    fn close(&mut self, label: Label, o: Open) {
        self.done.push(Segment {
            label,
            start: o.start,
            duration: o.last_speaking_end - o.start,
        });
    }

    /// Closes all open segments and returns every segment in start order.
    pub fn finish(mut self) -> Vec<Segment> {
        let open = std::mem::take(&mut self.open);
        for (l, o) in open {
            self.close(l, o);
        }
        self.done
            .sort_by(|a, b| a.start.total_cmp(&b.start).then(a.label.cmp(&b.label)));
        self.done
    }
}

/// RTTM text (`SPEAKER <file> 1 <start> <dur> <NA> <NA> <label> <NA> <NA>`) for the segments.
pub fn to_rttm(file_id: &str, segments: &[Segment]) -> String {
    let id = if file_id.is_empty() { "scene" } else { file_id };
    let id: String = id
        .chars()
        .map(|c| if c.is_whitespace() { '_' } else { c })
        .collect();
    segments
        .iter()
        .map(|s| {
            format!(
                "SPEAKER {id} 1 {:.3} {:.3} <NA> <NA> {} <NA> <NA>\n",
                s.start, s.duration, s.label
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_follow_speaking_with_hysteresis() {
        let a = Label::new(0, 0);
        let mut d = Diarizer::new(0.5, 0.3, 0.3);
        let probs = [0.1, 0.9, 0.8, 0.4, 0.2, 0.1, 0.1, 0.7, 0.7];
        for (k, p) in probs.iter().enumerate() {
            let t0 = k as f64 * 0.128;
            d.push(t0, t0 + 0.128, &[(a, *p)]);
        }
        let segs = d.finish();
        assert_eq!(segs.len(), 2, "{segs:?}");
        assert!((segs[0].start - 0.128).abs() < 1e-9);
        // Speaking ends with step 3 (p = 0.4 >= off), i.e. at 4 * 0.128.
        assert!((segs[0].duration - 3.0 * 0.128).abs() < 1e-9, "{segs:?}");
        assert!((segs[1].start - 7.0 * 0.128).abs() < 1e-9);
        let rttm = to_rttm("my scene", &segs);
        assert!(
            rttm.starts_with("SPEAKER my_scene 1 0.128 0.384 <NA> <NA> 0.0 <NA> <NA>\n"),
            "{rttm}"
        );
    }

    #[test]
    fn a_label_that_disappears_closes_its_segment() {
        let a = Label::new(3, 1);
        let mut d = Diarizer::new(0.5, 0.3, 1.0);
        d.push(0.0, 0.1, &[(a, 0.9)]);
        d.push(0.1, 0.2, &[]);
        let segs = d.finish();
        assert_eq!(
            segs,
            vec![Segment {
                label: a,
                start: 0.0,
                duration: 0.1
            }]
        );
    }
}
