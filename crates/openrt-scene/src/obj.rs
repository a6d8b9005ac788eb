//! Wavefront OBJ through `tobj`, behind a guard for what `tobj` mishandles.

/// The models of an OBJ file's bytes, through `tobj` (triangulated, one
/// index per vertex; `.mtl` files are not read).
///
/// Before `tobj` sees the text, every face, line and point index is checked
/// against the elements declared above it: `tobj` 4.0.5 multiplies indices
/// without a check (found by the `obj` fuzz target), which panics on
/// overflow in debug builds and reads the wrong element in release builds.
/// A panic inside `tobj` is also turned into an error.
///
/// # Errors
/// The line of a bad index, or `tobj`'s error for malformed text.
pub fn parse_obj(bytes: &[u8]) -> Result<Vec<tobj::Model>, String> {
    check_indices(bytes)?;
    let parsed = std::panic::catch_unwind(|| {
        tobj::load_obj_buf(&mut std::io::Cursor::new(bytes), &tobj::GPU_LOAD_OPTIONS, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
    });
    match parsed {
        Ok(Ok((models, _))) => Ok(models),
        Ok(Err(e)) => Err(e.to_string()),
        Err(_) => Err("the OBJ reader (tobj) failed on this file".into()),
    }
}

/// Every index of an `f`, `l` or `p` statement is a non-zero whole number
/// naming a `v`, `vt` or `vn` declared before it (negative: counted back).
fn check_indices(bytes: &[u8]) -> Result<(), String> {
    let mut counts = [0u64; 3];
    for (n, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => counts[0] += 1,
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            Some("f" | "l" | "p") => {
                for word in words {
                    for (k, part) in word.split('/').enumerate().filter(|(_, p)| !p.is_empty()) {
                        let kind = ["vertex", "texture coordinate", "normal"][k.min(2)];
                        let count = counts[k.min(2)];
                        let ok = part.parse::<i64>().is_ok_and(|i| i != 0 && i.unsigned_abs() <= count);
                        if !ok {
                            return Err(format!(
                                "line {}: {kind} index '{part}' does not name one of the {count} declared above it",
                                n + 1
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::parse_obj;

    #[test]
    fn indices_beyond_the_declared_elements_are_errors() {
        let good = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 -1/-1\n";
        assert_eq!(parse_obj(good).unwrap()[0].mesh.indices.len(), 3);
        // The fuzz finding: a relative texture index far out of range.
        let e = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 1\nf 1/1 3/-5 2\n").unwrap_err();
        assert!(
            e.contains("line 5") && e.contains("texture coordinate index '-5'"),
            "{e}"
        );
        for bad in [
            "v 0 0 0\nf 1 2 3\n",
            "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 0 1 2\n",
            "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1//9 2 3\n",
            "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 99999999999999999999\n",
            "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 x\n",
        ] {
            assert!(parse_obj(bad.as_bytes()).is_err(), "{bad}");
        }
    }
}
