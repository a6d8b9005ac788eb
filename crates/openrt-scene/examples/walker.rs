//! Writes the shipped glTF example `scenes/walker.glb`: a floor (static), a
//! spinning crate (affine) and a skinned tube that sways and walks
//! (deforming), made by [`openrt_scene::skinned_figure_glb`].
//!
//! ```sh
//! cargo run -p openrt-scene --example walker            # writes scenes/walker.glb
//! cargo run --release -p openrt -- play scenes/walker.glb -o target/walker
//! ```

use std::path::Path;

/// The shipped figure: about this many triangles in the tube...
pub const WALKER_TRIANGLES: usize = 3000;
/// ...skinned to this many joints.
pub const WALKER_BONES: usize = 6;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/walker.glb");
    openrt_core::write_atomically(&out, |w| w.write_all(&walker()))?;
    println!("wrote {}", out.display());
    Ok(())
}

/// The shipped scene's bytes.
#[must_use]
pub fn walker() -> Vec<u8> {
    openrt_scene::skinned_figure_glb(WALKER_TRIANGLES, WALKER_BONES)
}
