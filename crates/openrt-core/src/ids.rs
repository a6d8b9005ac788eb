//! Newtype handles with generation checks.

use std::fmt;

macro_rules! handle {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub struct $name {
            pub(crate) index: u32,
            pub(crate) generation: u32,
        }

        impl $name {
            /// Slot index (stable while the handle is alive).
            #[must_use]
            pub fn index(self) -> u32 {
                self.index
            }
            /// Generation of the slot when the handle was made; a handle
            /// from an earlier generation is stale.
            #[must_use]
            pub fn generation(self) -> u32 {
                self.generation
            }
        }

        impl fmt::Debug for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{}({}#{})", stringify!($name), self.index, self.generation)
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                fmt::Debug::fmt(self, f)
            }
        }
    };
}

handle!(
    /// An object (a geometry definition, like an OpenGL display list).
    ObjectId
);
handle!(
    /// An instance: an object placed in the world with a transform.
    InstanceId
);

/// A material in the context's material table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct MaterialId(pub(crate) u32);

impl MaterialId {
    /// The default material every context starts with.
    pub const DEFAULT: Self = Self(0);

    /// Index in the material table.
    #[must_use]
    pub fn index(self) -> u32 {
        self.0
    }
}

/// A texture in the context's texture table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TextureId(pub(crate) u32);

impl TextureId {
    /// Index in the texture table.
    #[must_use]
    pub fn index(self) -> u32 {
        self.0
    }
}
