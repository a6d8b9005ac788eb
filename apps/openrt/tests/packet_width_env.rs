//! `OPENRT_PACKET_LANES` forces the packet width of the `kd` backend (4 is
//! the width without AVX2, 32 the large packets of AVX2 CPUs, 8 and 16 one
//! register of AVX2 and of AVX-512); every
//! width renders the bytes of the single-ray path, with frustum culling and
//! without it (`OPENRT_NO_FRUSTUM`), over kd-trees and over BVHs
//! (`--backend bvh`, `bvh-single`).

use std::path::{Path, PathBuf};
use std::process::Command;

/// The CLI's variables (the library reads no environment).
const LANES_ENV: &str = "OPENRT_PACKET_LANES";
const NO_FRUSTUM_ENV: &str = "OPENRT_NO_FRUSTUM";

fn render(dir: &Path, tag: &str, backend: &str, lanes: Option<&str>, mode: &str, frustum: bool) -> Vec<u8> {
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
    cmd.env_remove(LANES_ENV);
    cmd.env_remove(NO_FRUSTUM_ENV);
    if !frustum {
        cmd.env(NO_FRUSTUM_ENV, "1");
    }
    if let Some(l) = lanes {
        cmd.env(LANES_ENV, l);
    }
    let status = cmd.status().expect("openrt runs");
    assert!(status.success(), "{tag}: openrt failed");
    std::fs::read(&out).unwrap()
}

#[test]
fn every_forced_width_gives_the_single_ray_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let dir: PathBuf = tmp.path().to_path_buf();
    for mode in ["gl", "whitted"] {
        let want = render(&dir, &format!("single-{mode}"), "kd-single", None, mode, true);
        let bvh_single = render(&dir, &format!("bvh-single-{mode}"), "bvh-single", None, mode, true);
        assert!(
            bvh_single == want,
            "{mode}: bvh-single gives other bytes than kd-single"
        );
        for lanes in ["4", "8", "16", "32"] {
            for frustum in [true, false] {
                let got = render(
                    &dir,
                    &format!("kd{lanes}-{mode}-{frustum}"),
                    "kd",
                    Some(lanes),
                    mode,
                    frustum,
                );
                assert!(
                    got == want,
                    "{mode}: {LANES_ENV} = {lanes}, frustum culling {frustum}, gives other bytes"
                );
                // The same packets over BVHs (`--backend bvh`: kd packets, `--accel bvh`).
                let bvh = render(
                    &dir,
                    &format!("bvh{lanes}-{mode}-{frustum}"),
                    "bvh",
                    Some(lanes),
                    mode,
                    frustum,
                );
                assert!(
                    bvh == want,
                    "{mode}: BVH packets of {lanes} lanes, frustum culling {frustum}, give other bytes"
                );
            }
        }
    }
}

/// A lane count that is no packet width stops the CLI with an error naming
/// the variable and the widths it takes, before it renders anything.
#[test]
fn a_width_that_is_no_packet_width_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    for bad in ["7", "64", "sixteen", "", "-4"] {
        let out = tmp.path().join("bad.png");
        let run = Command::new(env!("CARGO_BIN_EXE_openrt"))
            .args(["render", "--width", "8", "--height", "8", "-o"])
            .arg(&out)
            .env(LANES_ENV, bad)
            .output()
            .expect("openrt runs");
        assert!(!run.status.success(), "{LANES_ENV}={bad:?} accepted");
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(
            err.contains(&format!("{LANES_ENV}={bad}:")) && err.contains("4, 8, 16 or 32"),
            "{bad:?}: {err}"
        );
        assert!(!out.exists(), "{bad:?}: an image was written");
    }
}
