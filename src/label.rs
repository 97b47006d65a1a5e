//! Track labels: the identity of a tracked source.
//!
//! A label is the pair (birth step, index within that step), printed `"k.i"`. The tracker never
//! reuses a label within a session, so a label names one person for as long as they are tracked and
//! keys everything downstream (separated audio streams, events, diarization).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Identity of a track: born at tracker step `birth_step`, `index`-th birth of that step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Label {
    /// Tracker step at which the track was born.
    pub birth_step: u64,
    /// Index among the tracks born at that step.
    pub index: u32,
}

impl Label {
    /// A label born at `birth_step` with the given index.
    pub const fn new(birth_step: u64, index: u32) -> Self {
        Self { birth_step, index }
    }
}

impl fmt::Display for Label {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.birth_step, self.index)
    }
}

/// Error for a string that is not of the form `"k.i"`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid label {0:?}: expected \"<birth step>.<index>\", e.g. \"12.0\"")]
pub struct ParseLabelError(pub String);

impl FromStr for Label {
    type Err = ParseLabelError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = || ParseLabelError(s.to_string());
        let (k, i) = s.split_once('.').ok_or_else(err)?;
        let birth_step = k.parse().map_err(|_| err())?;
        let index = i.parse().map_err(|_| err())?;
        Ok(Self { birth_step, index })
    }
}

impl Serialize for Label {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl schemars::JsonSchema for Label {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "Label".into()
    }

    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        schemars::json_schema!({
            "type": "string",
            "pattern": "^[0-9]+\\.[0-9]+$",
            "description": "Track label \"<birth step>.<index>\", never reused within a session."
        })
    }
}

impl<'de> Deserialize<'de> for Label {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prints_and_parses_k_dot_i() {
        let l = Label::new(12, 3);
        assert_eq!(l.to_string(), "12.3");
        assert_eq!("12.3".parse::<Label>().unwrap(), l);
        assert_eq!(serde_json::to_string(&l).unwrap(), "\"12.3\"");
        assert_eq!(
            serde_json::from_str::<Label>("\"0.0\"").unwrap(),
            Label::new(0, 0)
        );
    }

    #[test]
    fn rejects_malformed_labels() {
        for bad in ["", "12", "12.", ".3", "a.b", "1.2.3", "-1.0"] {
            assert!(bad.parse::<Label>().is_err(), "{bad} accepted");
        }
    }
}
