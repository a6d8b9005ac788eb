//! Writing rendered images to files, atomically: the bytes go to a temporary
//! file beside the target, which is renamed over it only once everything was
//! written and synced. A write that fails part-way (a full disk) leaves no
//! truncated file, and a file already at the path is kept as it was.

use std::io::Write;
use std::path::Path;

use image::ImageEncoder;
use image::codecs::png::PngEncoder;

use crate::error::CoreError;
use crate::render::Image;

impl Image {
    /// The image as an `image` crate buffer (8-bit RGB, [`Image::to_rgb8`]),
    /// for any format or processing that crate offers.
    ///
    /// # Errors
    /// [`CoreError::Limit`] when the pixel count does not match the size (an
    /// image assembled by hand).
    pub fn to_rgb_image(&self) -> Result<image::RgbImage, CoreError> {
        let pixels = u64::from(self.width) * u64::from(self.height);
        image::RgbImage::from_raw(self.width, self.height, self.to_rgb8()).ok_or(CoreError::Limit {
            call: "Image::to_rgb_image",
            what: "pixel count".into(),
            value: self.pixels.len() as u64,
            limit: pixels,
        })
    }

    /// Writes the image as an 8-bit RGB PNG, atomically ([`write_atomically`]).
    ///
    /// # Errors
    /// [`CoreError::Write`] naming the file when it cannot be written; the
    /// path then holds what it held before (or nothing).
    pub fn save_png(&self, path: impl AsRef<Path>) -> Result<(), CoreError> {
        let path = path.as_ref();
        let bytes = self.to_rgb8();
        if bytes.len() as u64 != u64::from(self.width) * u64::from(self.height) * 3 {
            return Err(CoreError::Write {
                path: path.to_path_buf(),
                reason: format!(
                    "the image has {} pixels for its size {}x{}",
                    self.pixels.len(),
                    self.width,
                    self.height
                ),
            });
        }
        write_atomically(path, |w| {
            PngEncoder::new(w)
                .write_image(&bytes, self.width, self.height, image::ExtendedColorType::Rgb8)
                .map_err(std::io::Error::other)
        })
    }
}

/// The permissions of a file [`write_atomically`] finishes (Unix): read and
/// write for its owner, read for everyone else.
#[cfg(unix)]
pub const FINISHED_MODE: u32 = 0o644;

/// Writes a file atomically: `write` fills a temporary file in the target's
/// folder, which is synced and then renamed to `path`. When `write`, the
/// sync or the rename fails, the temporary file is removed and `path` keeps
/// what it held.
///
/// # Errors
/// [`CoreError::Write`] naming `path` and the cause.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), CoreError> {
    let fail = |e: std::io::Error| CoreError::Write {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".openrt-").suffix(".part");
    // A temporary file is private (0600); the finished file is readable as
    // one written in place would be.
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(FINISHED_MODE));
    let mut tmp = builder.tempfile_in(dir).map_err(fail)?;
    {
        let mut out = std::io::BufWriter::new(tmp.as_file_mut());
        write(&mut out).map_err(fail)?;
        out.flush().map_err(fail)?;
    }
    tmp.as_file().sync_all().map_err(fail)?;
    tmp.persist(path).map_err(|e| fail(e.error))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// A writer that accepts `budget` bytes and then fails, as a full disk does.
    struct FailsAfter<'a> {
        inner: &'a mut dyn Write,
        budget: usize,
    }

    impl Write for FailsAfter<'_> {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            if self.budget == 0 {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::StorageFull,
                    "no space left on device",
                ));
            }
            let n = buf.len().min(self.budget);
            self.budget -= n;
            self.inner.write(&buf[..n])
        }
        fn flush(&mut self) -> std::io::Result<()> {
            self.inner.flush()
        }
    }

    fn gradient(width: u32, height: u32) -> Image {
        let pixels = (0..width * height)
            .map(|i| {
                Vec3::new(
                    (i % width) as f32 / width as f32,
                    (i / width) as f32 / height as f32,
                    0.5,
                )
            })
            .collect();
        Image { width, height, pixels }
    }

    fn left_in(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn save_png_round_trips_through_the_image_crate() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.png");
        let img = gradient(37, 21);
        img.save_png(&path).unwrap();
        let back = image::open(&path).unwrap().to_rgb8();
        assert_eq!(back.dimensions(), (37, 21));
        assert_eq!(back.into_raw(), img.to_rgb8());
        assert_eq!(img.to_rgb_image().unwrap().into_raw(), img.to_rgb8());
        assert_eq!(
            left_in(dir.path()),
            vec!["a.png".to_owned()],
            "no temporary file is left"
        );
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode, FINISHED_MODE, "readable as a file written in place: {mode:o}");
        }
    }

    #[test]
    fn a_write_failing_part_way_leaves_no_file_and_keeps_the_old_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.png");
        for budget in [0, 1, 100, 5000] {
            let e = write_atomically(&path, |w| {
                let mut w = FailsAfter { inner: w, budget };
                w.write_all(&[7u8; 10_000])
            })
            .unwrap_err();
            assert!(matches!(&e, CoreError::Write { path: p, .. } if *p == path), "{e}");
            assert!(
                e.to_string().contains("frame.png") && e.to_string().contains("no space"),
                "{e}"
            );
            assert!(
                left_in(dir.path()).is_empty(),
                "budget {budget}: {:?}",
                left_in(dir.path())
            );
        }
        // A finished file is not lost to a later failed write of the same path.
        gradient(8, 8).save_png(&path).unwrap();
        let before = std::fs::read(&path).unwrap();
        let e = write_atomically(&path, |w| FailsAfter { inner: w, budget: 50 }.write_all(&before));
        assert!(e.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), before);
        assert_eq!(left_in(dir.path()), vec!["frame.png".to_owned()]);
    }

    #[test]
    fn unwritable_places_and_inconsistent_images_are_typed_errors() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("no/such/folder/x.png");
        let e = gradient(4, 4).save_png(&missing).unwrap_err();
        assert!(matches!(&e, CoreError::Write { path, .. } if *path == missing), "{e}");
        let broken = Image {
            width: 4,
            height: 4,
            pixels: vec![Vec3::ZERO; 3],
        };
        assert!(matches!(
            broken.save_png(dir.path().join("b.png")),
            Err(CoreError::Write { .. })
        ));
        assert!(matches!(
            broken.to_rgb_image(),
            Err(CoreError::Limit {
                value: 3,
                limit: 16,
                ..
            })
        ));
        assert!(left_in(dir.path()).is_empty());
    }
}
