//! Golden-image comparison shared by the scene tests.
//!
//! Goldens live in `tests/golden/` at the repository root; `OPENRT_BLESS=1`
//! rewrites them (look at them before committing).

use std::path::PathBuf;

use openrt_core::Image;

fn golden_path(name: &str) -> PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/golden")
        .join(format!("{name}.png"))
}

/// Compares with the golden, or rewrites it when `OPENRT_BLESS` is set.
pub fn check_golden(name: &str, img: &Image, max_rmse: f64, max_off_share: f64) {
    if std::env::var_os("OPENRT_BLESS").is_some() {
        image::save_buffer(
            golden_path(name),
            &img.to_rgb8(),
            img.width,
            img.height,
            image::ColorType::Rgb8,
        )
        .unwrap();
        return;
    }
    compare_golden(name, img, max_rmse, max_off_share);
}

/// Panics unless the RMSE is below `max_rmse` (in 1/255 units) and at most
/// `max_off_share` of the pixels are off by more than 8/255 in a channel.
pub fn compare_golden(name: &str, img: &Image, max_rmse: f64, max_off_share: f64) {
    let path = golden_path(name);
    let golden = image::open(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (bless with OPENRT_BLESS=1)", path.display()))
        .to_rgb8();
    assert_eq!(golden.dimensions(), (img.width, img.height), "{name}: size");
    let bytes = img.to_rgb8();
    let (mut se, mut off) = (0.0f64, 0usize);
    for (a, b) in golden.as_raw().chunks(3).zip(bytes.chunks(3)) {
        let d: Vec<i32> = a.iter().zip(b).map(|(&x, &y)| i32::from(x) - i32::from(y)).collect();
        se += d.iter().map(|&v| f64::from(v * v)).sum::<f64>() / 3.0;
        off += usize::from(d.iter().any(|v| v.abs() > 8));
    }
    let n = f64::from(img.width * img.height);
    let rmse = (se / n).sqrt();
    assert!(
        rmse < max_rmse && (off as f64) < max_off_share * n,
        "{name}: RMSE {rmse:.3}/255, {off} pixels off"
    );
}
