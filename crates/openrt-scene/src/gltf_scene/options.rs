//! What to play from a glTF file (scene, animation, camera), and how its
//! objects fall into the paper's motion classes.

/// Which scene, animation and camera of a glTF file to play.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct GltfOptions {
    /// `scenes[N]`; `None`: the file's default scene, else its first.
    pub scene: Option<usize>,
    /// The animation to play.
    pub animation: GltfAnimation,
    /// `cameras[N]` (its first node in the scene); `None`: the first
    /// perspective camera met, else one framing the scene.
    pub camera: Option<usize>,
}

/// The animations a glTF scene plays.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum GltfAnimation {
    /// The first animation (a warning names how many there are).
    #[default]
    First,
    /// `animations[N]`.
    Index(usize),
    /// The animation with this name.
    Name(String),
    /// Every animation at once, looping over the longest.
    All,
    /// None: the scene at rest.
    None,
}

impl std::str::FromStr for GltfAnimation {
    type Err = std::convert::Infallible;

    /// `all`, `none`, an index, else a name.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(match s {
            "all" => Self::All,
            "none" => Self::None,
            _ => s.parse().map_or_else(|_| Self::Name(s.to_string()), Self::Index),
        })
    }
}

/// A scene's instances and objects by the paper's motion classes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MotionClasses {
    /// Instances that never move, of objects never redefined.
    pub static_instances: usize,
    /// Instances whose transform changes from frame to frame.
    pub affine_instances: usize,
    /// Objects redefined every frame (skinned or morphed).
    pub deforming_objects: usize,
    /// Triangles of those objects.
    pub deforming_triangles: usize,
}

impl std::fmt::Display for MotionClasses {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} static instances, {} affine instances, {} deforming objects ({} triangles)",
            self.static_instances, self.affine_instances, self.deforming_objects, self.deforming_triangles
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn animation_choices_parse() {
        assert_eq!("all".parse(), Ok(GltfAnimation::All));
        assert_eq!("none".parse(), Ok(GltfAnimation::None));
        assert_eq!("2".parse(), Ok(GltfAnimation::Index(2)));
        assert_eq!("Walk".parse(), Ok(GltfAnimation::Name("Walk".into())));
        assert_eq!("-1".parse(), Ok(GltfAnimation::Name("-1".into())));
    }
}
