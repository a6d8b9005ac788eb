//! Primitive assembly: OpenGL-style vertex streams turned into triangles.

use crate::CoreError;

/// What `begin` starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PrimitiveKind {
    /// Independent triangles: every 3 vertices.
    Triangles,
    /// Strip: each vertex after the second makes a triangle with the two before it.
    TriangleStrip,
    /// Fan: each vertex after the second makes a triangle with the first and the previous.
    TriangleFan,
    /// Independent quads: every 4 vertices (split along the 0–2 diagonal).
    Quads,
    /// Quad strip: pairs of vertices make quads with the pair before.
    QuadStrip,
    /// One convex planar polygon (fan-triangulated).
    Polygon,
}

impl PrimitiveKind {
    /// Triangles (as vertex index triples, winding kept) for `n` vertices,
    /// or the rule that `n` breaks.
    pub(crate) fn triangulate(self, n: usize) -> Result<Vec<[usize; 3]>, CoreError> {
        let bad = |rule| {
            Err(CoreError::IncompletePrimitive {
                kind: self,
                count: n,
                rule,
            })
        };
        Ok(match self {
            Self::Triangles => {
                if !n.is_multiple_of(3) {
                    return bad("triangles need a multiple of 3 vertices");
                }
                (0..n / 3).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect()
            }
            Self::TriangleStrip => {
                if n < 3 {
                    return bad("a triangle strip needs at least 3 vertices");
                }
                (0..n - 2)
                    .map(|i| {
                        if i % 2 == 0 {
                            [i, i + 1, i + 2]
                        } else {
                            [i + 1, i, i + 2]
                        }
                    })
                    .collect()
            }
            Self::TriangleFan | Self::Polygon => {
                if n < 3 {
                    return bad("a fan or polygon needs at least 3 vertices");
                }
                (1..n - 1).map(|i| [0, i, i + 1]).collect()
            }
            Self::Quads => {
                if !n.is_multiple_of(4) {
                    return bad("quads need a multiple of 4 vertices");
                }
                (0..n / 4)
                    .flat_map(|q| [[4 * q, 4 * q + 1, 4 * q + 2], [4 * q, 4 * q + 2, 4 * q + 3]])
                    .collect()
            }
            Self::QuadStrip => {
                if n < 4 || !n.is_multiple_of(2) {
                    return bad("a quad strip needs an even number of vertices, at least 4");
                }
                (0..n / 2 - 1)
                    .flat_map(|q| {
                        let (a, b, c, d) = (2 * q, 2 * q + 1, 2 * q + 3, 2 * q + 2);
                        [[a, b, c], [a, c, d]]
                    })
                    .collect()
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_windings() {
        assert_eq!(PrimitiveKind::Triangles.triangulate(6).unwrap().len(), 2);
        assert_eq!(
            PrimitiveKind::TriangleStrip.triangulate(5).unwrap(),
            vec![[0, 1, 2], [2, 1, 3], [2, 3, 4]]
        );
        assert_eq!(
            PrimitiveKind::TriangleFan.triangulate(4).unwrap(),
            vec![[0, 1, 2], [0, 2, 3]]
        );
        assert_eq!(PrimitiveKind::Quads.triangulate(4).unwrap(), vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(PrimitiveKind::QuadStrip.triangulate(6).unwrap().len(), 4);
        assert_eq!(PrimitiveKind::Polygon.triangulate(8).unwrap().len(), 6);
        for (k, n) in [
            (PrimitiveKind::Triangles, 4),
            (PrimitiveKind::TriangleStrip, 2),
            (PrimitiveKind::Quads, 6),
            (PrimitiveKind::QuadStrip, 5),
            (PrimitiveKind::Polygon, 2),
        ] {
            assert!(
                matches!(k.triangulate(n), Err(CoreError::IncompletePrimitive { .. })),
                "{k:?} {n}"
            );
        }
    }
}
