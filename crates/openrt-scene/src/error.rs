//! Errors of the scene formats: each names the file and, where known, the line and column.

use std::path::PathBuf;

use thiserror::Error;

/// Why a scene could not be loaded.
#[derive(Debug, Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Malformed text.
    #[error("{path}:{line}:{col}: {msg}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        col: usize,
        /// What is wrong.
        msg: String,
    },
    /// A format version this build does not read.
    #[error("{path}: scene format version {found} is not supported (this build reads versions {supported})")]
    Version {
        /// The file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Versions understood.
        supported: &'static str,
    },
    /// A reference to something not defined in the file.
    #[error("{path}: {what} '{name}' is not defined (referenced by {by})")]
    Undefined {
        /// The file.
        path: PathBuf,
        /// Kind of thing: material, object, texture.
        what: &'static str,
        /// The name used.
        name: String,
        /// Who referenced it.
        by: String,
    },
    /// Content that parses but breaks a rule (bad index, NaN, bad count).
    #[error("{path}: {what}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The rule broken.
        what: String,
    },
    /// A texture file that is missing or not an image.
    #[error("texture {texture} (used by {path}): {msg}")]
    Texture {
        /// The texture file.
        texture: PathBuf,
        /// The scene file that uses it.
        path: PathBuf,
        /// The cause.
        msg: String,
    },
    /// The API refused a call while building the scene.
    #[error("{path}: {source}")]
    Core {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: openrt_core::CoreError,
    },
}

/// Something a lenient reader accepted in a file, with where it is: the
/// CLI prints a load's warnings once, the viewer shows them, and
/// `--strict` (`ScenePlayer::open_strict`) turns the first into an error.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SceneWarning {
    /// The file.
    pub path: PathBuf,
    /// 1-based line.
    pub line: usize,
    /// 1-based column.
    pub col: usize,
    /// What was done.
    pub msg: String,
}

impl std::fmt::Display for SceneWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Formats without lines (glTF's JSON paths are in the message) give line 0.
        if self.line == 0 {
            write!(f, "{}: {}", self.path.display(), self.msg)
        } else {
            write!(f, "{}:{}:{}: {}", self.path.display(), self.line, self.col, self.msg)
        }
    }
}

impl SceneWarning {
    /// The warning as a parse error (strict loading).
    #[must_use]
    pub fn into_error(self) -> SceneError {
        SceneError::Parse {
            path: self.path,
            line: self.line,
            col: self.col,
            msg: format!("{} (an error with --strict)", self.msg),
        }
    }
}
