//! Blade and vein as regions of space (dissertation §7.3, after the sphere/patch blend of
//! §4.8.4): what the non-manifold polygonizer needs to make the leaf.
//!
//! | id | region | rule, in order |
//! |---|---|---|
//! | 1 | vein | `Σ veins > |d| / r` ([`VeinRule::Dissertation`], the default) or `Σ veins > min(|d| / r, ½)` ([`VeinRule::Capped`]); with `Fillet::Below`, and not above the blade |
//! | 0 | beyond | beyond the blade's margin |
//! | 2 | above | `d > 0` |
//! | 3 | below | otherwise |
//!
//! `d` is the signed distance to the blade ([`crate::Blade::distance`]), `Σ veins` the sum
//! of the vein primitives and `r` the radius of the nearest vein. The vein test comes first
//! so that veins continue past the margin (the petiole, the rounded vein tips): the vein's
//! surface there is the pair (0, 1).
//!
//! The default is the dissertation's rule `Σ > |d|/r` (§7.3). Alone it makes a vein vanish
//! about a radius away from the blade, so a petiole is cut off where it leaves the leaf; the
//! capped rule ([`VeinRule::Capped`], ours) keeps it: a vein away from the blade is then its
//! own convolution surface (`Σ = ½`, radius `r`), and the dissertation's rule governs where
//! it matters, within half a radius of the blade, where the fillet forms. The generated
//! leaves with petioles use the capped rule (`vein_rule = "capped"` in their scenes).
//!
//! Surfaces of interest: (2, 3) the blade, (1, 2) and (1, 3) the vein above and below the
//! blade, (0, 1) the vein beyond the margin. Curves of interest: (0, 2, 3) the margin,
//! (1, 2, 3) where vein and blade meet, (0, 1, 2) and (0, 1, 3) where a vein leaves the blade
//! at the margin.
//!
//! Near the blade, `|d|` is small, so even a faint vein density claims the point: the vein
//! fillets smoothly into the blade (fig. 7.11). The localized variant (`Fillet::Below`)
//! keeps everything above the blade out of the vein, so the vein stands out only below and
//! the blade's upper side stays smooth (fig. 7.10, 7.12).

use glam::DVec3;
use skelform_field::RegionField;
use skelform_mesh::{RegionPair, RegionTriple};

use crate::blade::{Blade, Side};
use crate::veins::Veins;

/// Region id of space past the blade's margin and outside the veins: the outside of the leaf.
pub const BEYOND: u32 = 0;
/// Region id of the inside of a vein (the vein test comes first, so a vein continues past
/// the margin).
pub const VEIN: u32 = 1;
/// Region id of the space above the blade (positive signed distance), outside the veins.
pub const ABOVE: u32 = 2;
/// Region id of the space below the blade (negative signed distance), outside the veins.
pub const BELOW: u32 = 3;

/// Where a vein may fillet into the blade.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Fillet {
    /// Above and below (the dissertation's first blend, fig. 7.11).
    #[default]
    Both,
    /// Only below: a point above the blade is never in the vein (fig. 7.12).
    Below,
}

/// Which points near a vein are in it (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VeinRule {
    /// `Σ > |d|/r`, the dissertation's (§7.3): veins exist only near the blade.
    #[default]
    Dissertation,
    /// `Σ > min(|d|/r, ½)`: away from the blade a vein is its own convolution surface, so a
    /// petiole continues past the margin.
    Capped,
}

/// The region function of a blade with veins.
#[derive(Clone, Debug)]
pub struct BladeRegions {
    /// The blade whose signed distance `d` separates above, below and beyond.
    pub blade: Blade,
    /// The vein convolution; `None` for a bare blade, which then has only the regions beyond,
    /// above and below.
    pub veins: Option<Veins>,
    /// Whether veins fillet into the blade on both sides or only below.
    pub fillet: Fillet,
    /// Which points near a vein are in it.
    pub vein_rule: VeinRule,
}

impl BladeRegions {
    /// The surfaces to polygonize: blade, vein above, vein below, vein beyond (see the module
    /// documentation); only the blade when there are no veins.
    pub fn interest(&self) -> Vec<RegionPair> {
        if self.veins.is_some() {
            vec![
                RegionPair(BEYOND, VEIN),
                RegionPair(VEIN, ABOVE),
                RegionPair(VEIN, BELOW),
                RegionPair(ABOVE, BELOW),
            ]
        } else {
            vec![RegionPair(ABOVE, BELOW)]
        }
    }

    /// The curves where the surfaces of interest meet.
    pub fn curves(&self) -> Vec<RegionTriple> {
        let mut c = vec![RegionTriple::new([BEYOND, ABOVE, BELOW])];
        if self.veins.is_some() {
            c.extend([
                RegionTriple::new([VEIN, ABOVE, BELOW]),
                RegionTriple::new([BEYOND, VEIN, ABOVE]),
                RegionTriple::new([BEYOND, VEIN, BELOW]),
            ]);
        }
        c.sort();
        c
    }

    /// Points on each surface of interest to start the polygonizer from: the blade's
    /// vertices and the vein segments' ends.
    pub fn seeds(&self) -> Vec<DVec3> {
        let mut s: Vec<DVec3> = self.blade.vertices.iter().step_by(7).copied().collect();
        if let Some(v) = &self.veins {
            s.extend(v.segments.iter().map(|seg| seg.a + DVec3::Z * 0.5 * seg.radius));
        }
        s
    }
}

impl RegionField for BladeRegions {
    fn region(&self, p: DVec3) -> u32 {
        let d = self.blade.distance(p);
        if let Some(v) = &self.veins
            && !(self.fillet == Fillet::Below && d.side == Side::Above)
        {
            let (sum, r) = v.density(p);
            let threshold = match self.vein_rule {
                VeinRule::Dissertation => d.distance.abs() / r,
                VeinRule::Capped => (d.distance.abs() / r).min(skelform_skeleton::DEFAULT_ISO),
            };
            if sum > 0.0 && sum > threshold {
                return VEIN;
            }
        }
        match d.side {
            Side::Beyond => BEYOND,
            Side::Above => ABOVE,
            Side::Below => BELOW,
        }
    }

    /// Normals for the surfaces of interest (the chapter's `Gradient(p, pair)`), so that
    /// veins and blade shade smoothly instead of by averaged triangle normals: the blade's
    /// signed distance for the blade (2, 3), and `Σ − |d|/r` (`Σ − ½` where the capped rule
    /// caps it) for the vein surfaces, the function whose zero is the vein's boundary. The
    /// density's gradient is exact; the distance's is the nearest triangle's normal over the
    /// blade and a central difference beyond the margin.
    fn gradient(&self, p: DVec3, pair: (u32, u32)) -> Option<DVec3> {
        let h = 1e-6 * (1.0 + p.abs().max_element());
        let d = |q: DVec3| self.blade.distance(q).distance;
        let bd = self.blade.distance(p);
        // The nearest triangle's normal, turned to where d grows: ∇d over the blade (d is
        // the distance to its plane there), and the blade's normal up to its margin.
        let plane = || {
            let t = self.blade.triangles.get(bd.triangle)?;
            let [a, b, c] = t.map(|i| self.blade.vertices[i as usize]);
            let n = (b - a).cross(c - a).normalize_or_zero();
            (n != DVec3::ZERO).then(|| if d(p + n * h) >= d(p - n * h) { n } else { -n })
        };
        // Beyond the margin ∇d is a central difference (d is the distance to the margin).
        let blade_gradient = || match (bd.side, plane()) {
            (Side::Above | Side::Below, Some(n)) => n,
            _ => {
                DVec3::new(
                    d(p + DVec3::X * h) - d(p - DVec3::X * h),
                    d(p + DVec3::Y * h) - d(p - DVec3::Y * h),
                    d(p + DVec3::Z * h) - d(p - DVec3::Z * h),
                ) / (2.0 * h)
            }
        };
        match pair {
            (ABOVE, BELOW) => plane(),
            (a, b) if a == VEIN || b == VEIN => {
                let v = self.veins.as_ref()?;
                let (_, r) = v.density(p);
                if r == 0.0 {
                    return None;
                }
                let d = bd.distance;
                let capped = self.vein_rule == VeinRule::Capped
                    && d.abs() / r >= skelform_skeleton::DEFAULT_ISO;
                let threshold =
                    if capped { DVec3::ZERO } else { blade_gradient() * (d.signum() / r) };
                Some(v.density_gradient(p) - threshold)
            }
            _ => None,
        }
    }

    fn region_ids(&self) -> Option<Vec<u32>> {
        Some(if self.veins.is_some() {
            vec![BEYOND, VEIN, ABOVE, BELOW]
        } else {
            vec![BEYOND, ABOVE, BELOW]
        })
    }
}
