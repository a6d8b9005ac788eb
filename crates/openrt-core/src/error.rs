//! Errors of the API layer. Each names the call that was misused and the rule it broke.

use thiserror::Error;

use crate::{InstanceId, MaterialId, ObjectId, PrimitiveKind, TextureId};

/// A misuse of the API or bad input; the context is left unchanged by the failing call.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CoreError {
    /// A geometry call outside `begin_object`/`end_object`.
    #[error("{call}: not inside an object definition (call begin_object first)")]
    NotInObject {
        /// The call.
        call: &'static str,
    },
    /// A call that is not allowed inside an object definition.
    #[error("{call}: not allowed inside the definition of {object} (call end_object first)")]
    InsideObject {
        /// The call.
        call: &'static str,
        /// The object being defined.
        object: ObjectId,
    },
    /// `begin_object` while another definition is open.
    #[error("begin_object({object}): object definitions cannot nest; {current} is still being defined")]
    NestedObject {
        /// The object asked for.
        object: ObjectId,
        /// The open definition.
        current: ObjectId,
    },
    /// A vertex call outside `begin`/`end`.
    #[error("{call}: not inside begin/end of a primitive")]
    NotInPrimitive {
        /// The call.
        call: &'static str,
    },
    /// `begin` while a primitive is open, or `end_object` with one open.
    #[error("{call}: primitive {current:?} is still open (call end first)")]
    PrimitiveOpen {
        /// The call.
        call: &'static str,
        /// The open primitive.
        current: PrimitiveKind,
    },
    /// `end` with a vertex count that does not make whole primitives.
    #[error("end: {kind:?} got {count} vertices; {rule}")]
    IncompletePrimitive {
        /// The primitive.
        kind: PrimitiveKind,
        /// Vertices given.
        count: usize,
        /// The counting rule.
        rule: &'static str,
    },
    /// A stale or never-issued object id.
    #[error("{call}({id}): unknown object (never generated here, or deleted)")]
    UnknownObject {
        /// The call.
        call: &'static str,
        /// The id.
        id: ObjectId,
    },
    /// Instancing an object that has no definition yet.
    #[error("{call}({id}): object has never been defined (begin_object/end_object first)")]
    UndefinedObject {
        /// The call.
        call: &'static str,
        /// The id.
        id: ObjectId,
    },
    /// A stale or never-issued instance id.
    #[error("{call}({id}): unknown instance (never created here, or removed)")]
    UnknownInstance {
        /// The call.
        call: &'static str,
        /// The id.
        id: InstanceId,
    },
    /// A material id not in the table.
    #[error("{call}({id:?}): unknown material")]
    UnknownMaterial {
        /// The call.
        call: &'static str,
        /// The id.
        id: MaterialId,
    },
    /// A texture id not in the table.
    #[error("{call}({id:?}): unknown texture")]
    UnknownTexture {
        /// The call.
        call: &'static str,
        /// The id.
        id: TextureId,
    },
    /// `push_matrix` beyond the stack limit.
    #[error("push_matrix: matrix stack overflow (at most {limit} entries)")]
    StackOverflow {
        /// The limit.
        limit: usize,
    },
    /// `pop_matrix` with nothing pushed.
    #[error("pop_matrix: matrix stack underflow (nothing was pushed)")]
    StackUnderflow,
    /// NaN or infinity in a vertex, normal, coordinate or matrix.
    #[error("{call}: {what} is not finite (NaN or infinity)")]
    NonFinite {
        /// The call.
        call: &'static str,
        /// What was given.
        what: String,
    },
    /// A transform that can not be inverted.
    #[error(
        "{call}: singular or ill-conditioned transform (determinant {det:e}, |det| / longest column^3 = {conditioning:e}); instance transforms must be invertible with conditioning at least MIN_TRANSFORM_CONDITIONING = {min:e}",
        min = crate::MIN_TRANSFORM_CONDITIONING
    )]
    SingularTransform {
        /// The call.
        call: &'static str,
        /// Its determinant.
        det: f32,
        /// `|det| / longest column^3`.
        conditioning: f32,
    },
    /// A projective matrix where an affine one is needed.
    #[error("{call}: transform is not affine (last row {row:?}, expected [0, 0, 0, 1])")]
    NotAffine {
        /// The call.
        call: &'static str,
        /// The last row.
        row: [f32; 4],
    },
    /// An instance whose object was deleted, found at commit.
    #[error("commit: instance {instance} refers to deleted object {object}; remove the instance first")]
    InstanceOfDeletedObject {
        /// The instance.
        instance: InstanceId,
        /// The deleted object.
        object: ObjectId,
    },
    /// A traversal backend could not be set up for a frame.
    #[error("render: the {backend} backend failed: {reason}")]
    Backend {
        /// The backend's name.
        backend: &'static str,
        /// What it reported.
        reason: String,
    },
    /// An index of an indexed primitive beyond its vertex arrays.
    #[error("{call}: index {index} (element {at} of the indices) is beyond the {vertices} vertices of the arrays")]
    VertexIndex {
        /// The call.
        call: &'static str,
        /// The index given.
        index: u32,
        /// Its place in the index list.
        at: usize,
        /// Vertices in the arrays.
        vertices: usize,
    },
    /// Vertex arrays of different lengths.
    #[error("{call}: the {what} array has {len} entries; the positions have {vertices} (one per vertex is needed)")]
    ArrayLength {
        /// The call.
        call: &'static str,
        /// Which array.
        what: &'static str,
        /// Its length.
        len: usize,
        /// Number of positions.
        vertices: usize,
    },
    /// A value beyond a named limit, such as [`crate::MAX_IMAGE_SIDE`].
    #[error("{call}: {what} is {value}, outside the limit {limit}")]
    Limit {
        /// The call.
        call: &'static str,
        /// What was measured.
        what: String,
        /// The value given.
        value: u64,
        /// The limit it broke (a maximum, or 1 for a minimum of one).
        limit: u64,
    },
    /// A coordinate beyond [`crate::MAX_COORDINATE`] (a vertex after the
    /// matrix stack); the value is kept as given, in `f64`.
    #[error("{call}: {what} has largest |coordinate| {value:e}, outside the limit MAX_COORDINATE = {limit:e}")]
    CoordinateLimit {
        /// The call.
        call: &'static str,
        /// What was measured.
        what: String,
        /// The largest magnitude given (infinite or NaN when not finite).
        value: f64,
        /// The limit, [`crate::MAX_COORDINATE`].
        limit: f64,
    },
    /// A commit refused because an instance's world box leaves the coordinate
    /// range (a large object under a large scale): it could not be hit
    /// reliably. The instance and its object are named so that a program can
    /// remove or move the instance and commit again.
    #[error(
        "commit: instance {instance} of object {object} has the world box {min:?}..{max:?}, largest |coordinate| {largest:e}, outside the limit MAX_COORDINATE = {limit:e}; remove or move the instance and commit again"
    )]
    InstanceOutOfRange {
        /// The instance refused.
        instance: InstanceId,
        /// Its object.
        object: ObjectId,
        /// The world box's lower corner.
        min: [f32; 3],
        /// The world box's upper corner.
        max: [f32; 3],
        /// The box's largest |coordinate| (infinite or NaN when not finite).
        largest: f64,
        /// The limit, [`crate::MAX_COORDINATE`].
        limit: f64,
    },
    /// A hit given to [`crate::Scene::surface`] that another scene found.
    #[error(
        "surface: the hit (instance {instance}, triangle {prim}) was found in frame {hit_frame}, not in this scene (frame {scene_frame}), or names a triangle it does not have"
    )]
    ForeignHit {
        /// The hit's frame.
        hit_frame: u64,
        /// The scene's frame.
        scene_frame: u64,
        /// The hit's instance index.
        instance: u32,
        /// The hit's triangle.
        prim: u32,
    },
    /// A change set that does not fit the replica it was given to.
    #[error("apply_changes: {reason}")]
    Changes {
        /// What does not fit.
        reason: String,
    },
    /// The render pool could not start a thread, or a render thread failed.
    #[error("render: {reason}")]
    RenderThread {
        /// What happened, naming the thread.
        reason: String,
    },
    /// A file could not be written (a full disk, a missing folder, no
    /// permission); the path keeps what it held before.
    #[error("{}: cannot write: {reason}", path.display())]
    Write {
        /// The file.
        path: std::path::PathBuf,
        /// The cause.
        reason: String,
    },
    /// The acceleration layer refused the input.
    #[error("{call}: {source}")]
    Accel {
        /// The call.
        call: &'static str,
        /// The cause.
        source: openrt_accel::AccelError,
    },
}
