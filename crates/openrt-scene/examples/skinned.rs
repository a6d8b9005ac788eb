//! Per-frame times of a skinned figure played through the API: skinning,
//! redefinition, the build (refit) in the commit and the rest of the commit,
//! as the bench's deforming table measures them, frame by frame.
//!
//! ```sh
//! cargo run --release -p openrt-scene --example skinned -- 100000 2 16 bvh|kd
//! ```

use openrt_core::Accel;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: &str| args.get(i).cloned().unwrap_or_else(|| d.to_string());
    let n: usize = arg(1, "100000").parse()?;
    let threads: usize = arg(2, "2").parse()?;
    let frames: u32 = arg(3, "16").parse()?;
    let accel = if arg(4, "bvh") == "kd" { Accel::Kd } else { Accel::Bvh };
    let bytes = openrt_scene::skinned_figure_glb(n, 8);
    let mut p = openrt_scene::GltfPlayer::from_slice(&bytes)?;
    p.ctx.set_threads(threads)?;
    p.ctx.set_promote_after(None);
    p.ctx.set_accel(accel);
    p.set_deforming_accel(None)?;
    p.set_time(0.0)?;
    let mut sums = Vec::new();
    for f in 1..=frames {
        let st = p.set_time(p.time_of(f))?;
        let d = p.deform_times();
        let b: f64 = st.builds.iter().map(|b| b.ms).sum();
        let refit = st.builds.iter().all(|b| b.refitted);
        println!(
            "frame {f:2}: skin {:6.2} define {:6.2} build {:6.2} ({}) rest {:5.2}",
            d.skin_ms,
            d.define_ms,
            b,
            if refit { "refit" } else { "built" },
            st.total_ms - b
        );
        sums.push(d.skin_ms + b);
    }
    let mut first = sums[..sums.len().min(8)].to_vec();
    first.sort_by(f64::total_cmp);
    let mut all = sums.clone();
    all.sort_by(f64::total_cmp);
    println!(
        "skin + build median: first 8 frames {:.2} ms, all {:.2} ms",
        first[first.len() / 2],
        all[all.len() / 2]
    );
    Ok(())
}
