//! `OPENRT_PACKET_LANES` forces the packet width of the `kd` backend (4 is
//! the portable baseline, 8 and 16 the AVX2 and AVX-512 widths); every
//! width renders the bytes of the single-ray path.

use std::path::{Path, PathBuf};
use std::process::Command;

fn render(dir: &Path, tag: &str, backend: &str, lanes: Option<&str>, mode: &str) -> Vec<u8> {
    let out = dir.join(format!("{tag}.png"));
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_openrt"));
    cmd.args([
        "render",
        "--width",
        "96",
        "--height",
        "64",
        "--threads",
        "2",
        "--mode",
        mode,
    ])
    .args(["--backend", backend, "-o"])
    .arg(&out);
    cmd.env_remove(openrt_accel::LANES_ENV);
    if let Some(l) = lanes {
        cmd.env(openrt_accel::LANES_ENV, l);
    }
    let status = cmd.status().expect("openrt runs");
    assert!(status.success(), "{tag}: openrt failed");
    std::fs::read(&out).unwrap()
}

#[test]
fn every_forced_width_gives_the_single_ray_bytes() {
    let dir: PathBuf = std::env::temp_dir().join(format!("openrt-lanes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for mode in ["gl", "whitted"] {
        let want = render(&dir, &format!("single-{mode}"), "kd-single", None, mode);
        for lanes in ["4", "8", "16"] {
            let got = render(&dir, &format!("kd{lanes}-{mode}"), "kd", Some(lanes), mode);
            assert!(
                got == want,
                "{mode}: {} = {lanes} gives other bytes",
                openrt_accel::LANES_ENV
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
