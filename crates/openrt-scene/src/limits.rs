//! The scene formats' limits. Each is checked where the value is read, and
//! breaking one gives an error that names the file, the line where known, and
//! the limit. The renderer's own limits (image size, depth, threads) are in
//! `openrt_core` ([`openrt_core::MAX_IMAGE_SIDE`] and the others) and apply
//! to a scene's resolution as well.

/// Largest count in an AFF header (`m` vertex/normal/texture/triangle
/// counts, `p` and `pp` vertex counts, `tpa` sample counts, key counts).
/// Memory is reserved for at most as many items as tokens remain in the input.
pub const MAX_HEADER_COUNT: usize = 50_000_000;

/// Deepest nesting of AFF `xs` and `x` blocks.
pub const MAX_BLOCK_NESTING: usize = 256;

/// Deepest nesting of AFF include files (guards against include cycles).
pub const MAX_INCLUDE_DEPTH: usize = 32;

/// Most `i` (include) commands processed for one scene, nested or not
/// (guards against include trees that multiply: 10 includes of a file
/// that includes 10 more, and so on).
pub const MAX_INCLUDES: usize = 10_000;

/// Most triangles one scene file may define (before instancing), whether
/// read from AFF, RON or OBJ or generated.
pub const MAX_SCENE_TRIANGLES: usize = 20_000_000;

/// Largest scene file read (AFF, RON, OBJ), in bytes.
pub const MAX_FILE_BYTES: u64 = 1 << 31;

/// Most cells per edge of a `Terrain` generator's heightfield.
pub const MAX_TERRAIN_GRID: u32 = 4096;

/// Most tree instances of a `Terrain` generator.
pub const MAX_TREES: u32 = 1_000_000;

/// Most triangles of one generated tree object.
pub const MAX_TREE_TRIANGLES: u32 = 1_000_000;

/// Most generated museum animart triangles (`animart_triangles`).
pub const MAX_ANIMART_TRIANGLES: u32 = 4_000_000;

/// Most stacks of a RON `Sphere` (it has twice as many slices).
pub const MAX_SPHERE_SEGMENTS: u32 = 256;

/// Most frames of an animation.
pub const MAX_FRAMES: u32 = 10_000_000;

/// Longest texture side, in texels.
pub const MAX_TEXTURE_SIDE: u32 = 16_384;

/// Most texels of one texture (each takes 12 bytes once loaded).
pub const MAX_TEXTURE_TEXELS: u64 = 1 << 25;

/// Reads a whole file of at most [`MAX_FILE_BYTES`].
pub(crate) fn read_file(path: &std::path::Path) -> Result<Vec<u8>, crate::SceneError> {
    use std::io::Read;
    let io = |source| crate::SceneError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let too_big = || crate::SceneError::Invalid {
        path: path.to_path_buf(),
        what: format!("the file is larger than the limit of {MAX_FILE_BYTES} bytes (MAX_FILE_BYTES)"),
    };
    if file.metadata().map_err(io)?.len() > MAX_FILE_BYTES {
        return Err(too_big());
    }
    let mut bytes = Vec::new();
    file.take(MAX_FILE_BYTES + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(too_big());
    }
    Ok(bytes)
}
