//! Which pose a model is drawn in (`--animation`, `--time`), and the animations a file has, as
//! `info` lists them. The glTF importer computes the pose (animations sampled, skins, morph
//! targets); OBJ files have none.

use serde::Serialize;

/// Which pose to draw (`--animation`, `--time`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PoseOptions {
    /// The animation, by name or index; `None` with a `time` means animation 0.
    pub animation: Option<String>,
    /// Seconds into the animation; `None` with an `animation` means 0. Must be finite and
    /// non-negative (checked by [`PoseOptions::check`]).
    pub time: Option<f32>,
}

impl PoseOptions {
    /// Refuses a time that is NaN, infinite or negative.
    pub fn check(&self) -> Result<(), String> {
        match self.time {
            Some(t) if !t.is_finite() || t < 0.0 => Err(format!(
                "--time {t}: must be a finite number of seconds, 0 or more"
            )),
            _ => Ok(()),
        }
    }

    /// Whether any animation is asked for.
    pub fn animates(&self) -> bool {
        self.animation.is_some() || self.time.is_some()
    }
}

/// One animation of the file, as `info` lists it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AnimationInfo {
    /// Index in the file.
    pub index: usize,
    /// Name, if the file gives one.
    pub name: Option<String>,
    /// The last keyframe time over all its channels, in seconds (0 when it cannot be read).
    pub duration: f32,
    /// Number of channels.
    pub channels: usize,
}

impl AnimationInfo {
    /// `0 'Walk'` or `3`.
    pub fn label(&self) -> String {
        match &self.name {
            Some(name) => format!("{} '{name}'", self.index),
            None => self.index.to_string(),
        }
    }
}

/// The index of the animation `wanted` names (a name first, then an index), or an error
/// listing those there are (as `--animation` chooses; `None` is animation 0).
pub fn choose_animation(
    animations: &[AnimationInfo],
    wanted: Option<&str>,
) -> Result<usize, String> {
    let list = || {
        if animations.is_empty() {
            "the file has no animations".to_string()
        } else {
            let names: Vec<String> = animations.iter().map(AnimationInfo::label).collect();
            format!("the file has {}", names.join(", "))
        }
    };
    let Some(wanted) = wanted else {
        return if animations.is_empty() {
            Err(format!("--time needs an animation: {}", list()))
        } else {
            Ok(0)
        };
    };
    if let Some(a) = animations
        .iter()
        .find(|a| a.name.as_deref() == Some(wanted))
    {
        return Ok(a.index);
    }
    match wanted.parse::<usize>() {
        Ok(i) if i < animations.len() => Ok(i),
        _ => Err(format!("no animation '{wanted}'; {}", list())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_must_be_finite_and_not_negative() {
        let at = |t| PoseOptions {
            animation: None,
            time: Some(t),
        };
        assert!(at(0.0).check().is_ok());
        assert!(at(f32::NAN).check().is_err());
        assert!(at(-1.0).check().is_err());
        assert!(at(f32::INFINITY).check().is_err());
    }
}
