//! Which structure the top level is: the paper's BSP over instance boxes,
//! or a wide BVH over them, chosen per commit.

/// Instances from which [`TopLevel::Auto`] builds a BVH top level.
///
/// PERF: BVH against BSP top level, kd objects, the default backend's
/// packets: terrain (662 instances) frames 0.93-0.96 of the time (queries:
/// primary packets 0.90, single rays 0.73); robots (161) frames 0.97
/// GL-like, 0.996 Whitted (single rays 1.03-1.06); kitchen (6) GL-like
/// 1.00, Whitted 1.007, and museum1k (2) 0.98, but single rays there take
/// 1.11-1.14 (a node test per ray against the BSP's single leaf).
pub const TOP_LEVEL_BVH_MIN: usize = 64;

/// The structure over the instances' world boxes, rebuilt by every commit
/// in which a box moved ([`crate::Context::set_top_level`]). Both find the
/// same hits: a ray tests the instances whose world box it reaches before
/// its closest hit, and each instance's answer is its own tree's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum TopLevel {
    /// The BSP up to [`TOP_LEVEL_BVH_MIN`] instances, a BVH from there.
    #[default]
    Auto,
    /// The paper's BSP (Wald, Benthin & Slusallek 2003, Algorithm 1).
    Bsp,
    /// A four-wide BVH over the instance boxes
    /// ([`openrt_accel::InstanceBvh`]).
    Bvh,
}

impl TopLevel {
    /// Every choice.
    pub const ALL: [Self; 3] = [Self::Auto, Self::Bsp, Self::Bvh];

    /// The name used by the CLI and RON scenes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Bsp => "bsp",
            Self::Bvh => "bvh",
        }
    }

    /// Whether a scene of `instances` instances gets a BVH top level.
    #[must_use]
    pub fn uses_bvh(self, instances: usize) -> bool {
        match self {
            Self::Auto => instances >= TOP_LEVEL_BVH_MIN,
            Self::Bsp => false,
            Self::Bvh => true,
        }
    }
}

impl std::str::FromStr for TopLevel {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|t| t.name() == s)
            .ok_or_else(|| format!("unknown top level {s:?}: expected auto, bsp or bvh"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_takes_a_bvh_from_the_limit_and_names_round_trip() {
        assert!(!TopLevel::Auto.uses_bvh(TOP_LEVEL_BVH_MIN - 1));
        assert!(TopLevel::Auto.uses_bvh(TOP_LEVEL_BVH_MIN));
        assert!(!TopLevel::Bsp.uses_bvh(1 << 20) && TopLevel::Bvh.uses_bvh(0));
        for t in TopLevel::ALL {
            assert_eq!(t.name().parse::<TopLevel>(), Ok(t));
        }
        assert!("kd".parse::<TopLevel>().unwrap_err().contains("auto, bsp or bvh"));
    }
}
