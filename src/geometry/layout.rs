//! The calibrated sensor layout of one room (one session).

use super::{Aabb, Camera, GeometryError, MicArray};

/// Every sensor of a room with its calibration, and the shared acoustic constants.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Audio sample rate in Hz.
    pub sample_rate: u32,
    /// Speed of sound in m/s.
    pub speed_of_sound: f64,
    /// Microphone arrays; the first array's first channel is the reference microphone.
    pub arrays: Vec<MicArray>,
    /// Cameras (possibly none).
    pub cameras: Vec<Camera>,
    /// Where sources can be; bounds searches, births and clutter.
    pub region: Option<Aabb>,
}

impl Layout {
    /// Validates a layout: at least one array, unique ids, and audio channels that form exactly
    /// `0..n` when any array carries channels.
    pub fn new(
        sample_rate: u32,
        speed_of_sound: f64,
        arrays: Vec<MicArray>,
        cameras: Vec<Camera>,
        region: Option<Aabb>,
    ) -> Result<Self, GeometryError> {
        if !(1000..=384_000).contains(&sample_rate) {
            return Err(GeometryError::new(
                "sample_rate",
                "must be between 1000 and 384000 Hz",
            ));
        }
        if !(speed_of_sound.is_finite() && (200.0..=500.0).contains(&speed_of_sound)) {
            return Err(GeometryError::new(
                "speed_of_sound",
                "must be between 200 and 500 m/s",
            ));
        }
        if arrays.is_empty() {
            return Err(GeometryError::new(
                "arrays",
                "must list at least one microphone array",
            ));
        }
        for (i, a) in arrays.iter().enumerate() {
            if arrays[..i].iter().any(|b| b.id == a.id) {
                return Err(GeometryError::new(
                    format!("arrays[{i}].id"),
                    format!("duplicate id {:?}", a.id),
                ));
            }
        }
        for (i, c) in cameras.iter().enumerate() {
            if cameras[..i].iter().any(|d| d.id == c.id) {
                return Err(GeometryError::new(
                    format!("cameras[{i}].id"),
                    format!("duplicate id {:?}", c.id),
                ));
            }
        }
        let mut seen: Vec<usize> = arrays
            .iter()
            .flat_map(|a| a.channels.iter().copied())
            .collect();
        if !seen.is_empty() {
            if let Some((i, _)) = arrays
                .iter()
                .enumerate()
                .find(|(_, a)| a.channels.is_empty())
            {
                return Err(GeometryError::new(
                    format!("arrays[{i}].channels"),
                    "is empty while other arrays carry audio channels",
                ));
            }
            seen.sort_unstable();
            for (expect, &got) in seen.iter().enumerate() {
                if got != expect {
                    let msg = if expect > 0 && seen[expect - 1] == got {
                        format!("channel {got} is used twice")
                    } else {
                        format!(
                            "channel {expect} belongs to no array (channels must be 0..{})",
                            seen.len()
                        )
                    };
                    return Err(GeometryError::new("arrays[].channels", msg));
                }
            }
        }
        Ok(Self {
            sample_rate,
            speed_of_sound,
            arrays,
            cameras,
            region,
        })
    }

    /// Total number of audio channels carried by the arrays.
    pub fn channel_count(&self) -> usize {
        self.arrays.iter().map(|a| a.channels.len()).sum()
    }

    /// The audio column of the reference microphone (`arrays[0].channels[0]`), if audio exists.
    pub fn reference_channel(&self) -> Option<usize> {
        self.arrays
            .first()
            .and_then(|a| a.channels.first().copied())
    }

    /// Index of the array with the given id.
    pub fn array_index(&self, id: &str) -> Option<usize> {
        self.arrays.iter().position(|a| a.id == id)
    }

    /// Index of the camera with the given id.
    pub fn camera_index(&self, id: &str) -> Option<usize> {
        self.cameras.iter().position(|c| c.id == id)
    }
}

#[cfg(test)]
mod tests {
    use super::super::Vec3;
    use super::*;

    fn arr(id: &str, channels: Vec<usize>) -> MicArray {
        let mics = (0..channels.len().max(2))
            .map(|i| Vec3::new(0.05 * i as f64, 0.0, 1.0))
            .collect();
        MicArray::new(id, mics, channels).unwrap()
    }

    #[test]
    fn channels_must_partition_the_audio_columns() {
        assert!(
            Layout::new(
                16000,
                343.0,
                vec![arr("a", vec![0, 1]), arr("b", vec![2, 3])],
                vec![],
                None
            )
            .is_ok()
        );
        let e = Layout::new(
            16000,
            343.0,
            vec![arr("a", vec![0, 1]), arr("b", vec![1, 2])],
            vec![],
            None,
        )
        .unwrap_err();
        assert!(e.message.contains("twice"), "{e}");
        let e = Layout::new(16000, 343.0, vec![arr("a", vec![0, 2])], vec![], None).unwrap_err();
        assert!(e.message.contains("belongs to no array"), "{e}");
        let e = Layout::new(
            16000,
            343.0,
            vec![arr("a", vec![0, 1]), arr("a", vec![2, 3])],
            vec![],
            None,
        )
        .unwrap_err();
        assert_eq!(e.field, "arrays[1].id");
    }

    #[test]
    fn reference_channel_is_first_of_first_array() {
        let l = Layout::new(16000, 343.0, vec![arr("a", vec![3, 2, 1, 0])], vec![], None).unwrap();
        assert_eq!(l.reference_channel(), Some(3));
        assert_eq!(l.channel_count(), 4);
    }
}
