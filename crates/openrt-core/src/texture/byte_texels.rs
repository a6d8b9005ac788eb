//! Texels kept as bytes where bytes hold them exactly.
//!
//! The loaders make texels `byte / 255` ([`crate::Texture::new`] takes any
//! finite values). A level whose every channel is such a value is also
//! stored as four bytes per texel, which the lookups read instead of the
//! 16-byte `Vec3A`: a quarter of the memory, so scattered lookups (bounce
//! hits of a Whitted frame) miss the caches less. [`decode`] gives the
//! stored value back bit for bit (`f32::from(byte) / 255`, one correctly
//! rounded division, as the loaders compute it), so images do not change.
//! Levels of other values (mipmap averages, HDR texels) keep only the
//! floats.

use glam::Vec3A;

/// `t`'s channels as bytes when each is exactly `byte / 255` in f32, the
/// fourth byte zero; `None` otherwise.
fn encode(t: Vec3A) -> Option<[u8; 4]> {
    let byte = |c: f32| {
        if !(0.0..=1.0).contains(&c) {
            return None;
        }
        // In range: the cast neither saturates nor meets a NaN.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let b = (c * 255.0).round() as u8;
        (f32::from(b) / 255.0).to_bits().eq(&c.to_bits()).then_some(b)
    };
    Some([byte(t.x)?, byte(t.y)?, byte(t.z)?, 0])
}

/// Every texel of `texels` as bytes ([`encode`]), or an empty vector when
/// some texel is not exactly bytes.
pub(super) fn encode_all(texels: &[Vec3A]) -> Vec<[u8; 4]> {
    texels
        .iter()
        .map(|&t| encode(t))
        .collect::<Option<Vec<_>>>()
        .unwrap_or_default()
}

/// The texel of bytes `b`: `f32::from(b[i]) / 255` per channel, the bits
/// [`encode`] took them from.
#[allow(clippy::inline_always)]
#[inline(always)]
pub(super) fn decode(b: [u8; 4]) -> Vec3A {
    Vec3A::new(f32::from(b[0]), f32::from(b[1]), f32::from(b[2])) / 255.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_byte_value_round_trips_bit_for_bit() {
        for b in 0..=255u8 {
            let byte = |b: u8| f32::from(b) / 255.0;
            let t = Vec3A::new(byte(b), byte(255 - b), byte(b / 3));
            let bytes = encode(t).expect("byte values encode");
            assert_eq!(bytes, [b, 255 - b, b / 3, 0]);
            assert_eq!(
                decode(bytes).to_array().map(f32::to_bits),
                t.to_array().map(f32::to_bits),
                "{b}"
            );
        }
        let all: Vec<Vec3A> = (0..=255u8).map(|b| Vec3A::splat(f32::from(b) / 255.0)).collect();
        let bytes = encode_all(&all);
        assert_eq!(bytes.len(), 256);
        for (t, b) in all.iter().zip(&bytes) {
            assert_eq!(decode(*b).to_array().map(f32::to_bits), t.to_array().map(f32::to_bits));
        }
    }

    #[test]
    fn values_that_are_not_bytes_keep_their_floats() {
        let byte = f32::from(7u8) / 255.0;
        for odd in [
            0.5,
            f32::from_bits(byte.to_bits() + 1),
            -0.0,
            -1.0 / 255.0,
            1.0 + f32::EPSILON,
            2.0,
            f32::NAN,
        ] {
            assert_eq!(encode(Vec3A::new(byte, odd, byte)), None, "{odd}");
            // One such texel keeps the whole level in floats.
            assert!(encode_all(&[Vec3A::splat(byte), Vec3A::new(byte, byte, odd)]).is_empty());
        }
        assert_eq!(encode(Vec3A::new(0.0, 1.0, byte)), Some([0, 255, 7, 0]));
    }
}
