//! A mailbox of the triangles a packet has tested in one tree walk.
//!
//! A kd-tree references a triangle from every leaf whose cell it crosses
//! (about 1.9 references per triangle in the SAH trees here), so a packet
//! walking neighbouring leaves meets many triangles twice: a fifth of the
//! kitchen's primary-packet triangle tests were repeats, nearly all for lanes
//! that had tested them already. Mailboxing (Amanatides & Woo 1987; Havran's
//! thesis, 2000, for kd-trees) skips them: a lane that has tested a
//! triangle in this walk gets nothing new from it, because a closest-hit
//! lane's bound has since only come down to its hits (a hit at `t` leaves a
//! bound of at most `t`, and the test needs `t` below the bound), and an
//! any-hit lane that was blocked has left the walk.

/// Slots of the mailbox: triangles map to a slot by their index.
const SLOTS: usize = 32;

/// Per slot, the last triangle index stored there and the lanes that have
/// tested it; a lookup is one compare, and a triangle pushed out of its slot
/// is only tested again (never skipped wrongly).
pub(crate) struct TriMailbox([(u32, u32); SLOTS]);

impl TriMailbox {
    /// An empty mailbox: no lane has tested anything.
    #[inline]
    pub(crate) const fn new() -> Self {
        Self([(u32::MAX, 0); SLOTS])
    }

    /// The lanes of `lanes` that have not tested triangle `prim` yet, which
    /// are from now on recorded as having tested it.
    #[inline]
    pub(crate) fn untested(&mut self, prim: u32, lanes: u32) -> u32 {
        let slot = &mut self.0[prim as usize % SLOTS];
        if slot.0 == prim {
            let fresh = lanes & !slot.1;
            slot.1 |= lanes;
            fresh
        } else {
            *slot = (prim, lanes);
            lanes
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_lanes_that_tested_a_triangle_skip_it() {
        let mut m = TriMailbox::new();
        // An empty slot holds no lanes, whatever index is asked for.
        assert_eq!(m.untested(u32::MAX, 0b1111), 0b1111);
        assert_eq!(m.untested(7, 0b0011), 0b0011);
        assert_eq!(m.untested(7, 0b0111), 0b0100);
        assert_eq!(m.untested(7, 0b0111), 0);
        // Another triangle in the same slot pushes 7 out: 7 is tested again.
        assert_eq!(m.untested(7 + SLOTS as u32, 0b0001), 0b0001);
        assert_eq!(m.untested(7, 0b0001), 0b0001);
        // Other slots are untouched.
        assert_eq!(m.untested(8, 0b1000), 0b1000);
        assert_eq!(m.untested(7, 0b0001), 0);
    }
}
