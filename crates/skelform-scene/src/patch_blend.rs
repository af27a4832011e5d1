//! `[regions.patch_blend]`: the chapter's blend of a sphere-like bump to a bicubic patch
//! (dissertation §4.8.4) as a built-in region function, since its region test needs the
//! nearest point on the patch, which formulas cannot express.
//!
//! ```toml
//! [regions]
//! interest = [[1, 2], [1, 3], [2, 3]]   # the default with a patch blend
//! [regions.patch_blend]
//! control = [                           # 4 rows (s = 0, ⅓, ⅔, 1) of 4 points (t)
//!   [[-1, -1, 0], [-1, -0.3, 0], [-1, 0.3, 0], [-1, 1, 0]],
//!   ...
//! ]
//! centre = [0, 0, 0]     # the bump's centre; default the patch's centre P(½, ½)
//! radius = 0.714         # the bump's radius; default the saucer's 1/1.4
//! height = 0.35          # its height; default the saucer's 0.35
//! ```
//!
//! Regions, as the chapter numbers them: 0 beyond the patch's border, 1 the bump, 2 on the
//! side of the patch its normal `Pₛ × Pₜ` points to, 3 on the other.

use serde::Deserialize;
use skelform_field::DVec3;
use skelform_leaf::patch::{BicubicPatch, PatchBlend};
use skelform_mesh::RegionPair;
use toml::Spanned;

use crate::SceneError;
use crate::diag::At;

/// The region ids of a patch blend: beyond, bump, above, below.
pub(crate) const IDS: [u32; 4] = [0, 1, 2, 3];

/// The surfaces of the chapter's example: the bump above and below the patch, and the patch.
pub(crate) const INTEREST: [RegionPair; 3] = [RegionPair(1, 2), RegionPair(1, 3), RegionPair(2, 3)];

/// The saucer's bump (§4.8.1), which the chapter's patch blend varies.
const SAUCER_RADIUS: f64 = 1.0 / 1.4;
const SAUCER_HEIGHT: f64 = 0.35;

/// One row of control points, each where it is written.
type Row = Spanned<Vec<Spanned<[f64; 3]>>>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct PatchBlendSection {
    control: Spanned<Vec<Row>>,
    centre: Option<Spanned<[f64; 3]>>,
    radius: Option<Spanned<f64>>,
    height: Option<Spanned<f64>>,
}

/// Checks the table and makes the region function; `at(offset, message)` makes a
/// positioned error.
pub(crate) fn build(sec: &PatchBlendSection, at: At) -> Result<PatchBlend, SceneError> {
    let rows = sec.control.get_ref();
    let shape = "a bicubic patch has 4 rows of 4 control points [x, y, z]";
    if rows.len() != 4 {
        return Err(at(
            sec.control.span().start,
            format!("'control' has {} rows; {shape}", rows.len()),
        ));
    }
    let mut control = [[DVec3::ZERO; 4]; 4];
    for (i, row) in rows.iter().enumerate() {
        if row.get_ref().len() != 4 {
            return Err(at(
                row.span().start,
                format!("row {} of 'control' has {} points; {shape}", i + 1, row.get_ref().len()),
            ));
        }
        for (j, point) in row.get_ref().iter().enumerate() {
            let p = DVec3::from_array(*point.get_ref());
            if !p.is_finite() {
                return Err(at(point.span().start, "control points must be finite numbers".into()));
            }
            control[i][j] = p;
        }
    }
    let patch = BicubicPatch::new(control);
    let [_, ps, pt] = patch.eval(0.5, 0.5);
    if ps.cross(pt).length() <= 1e-12 * (ps.length_squared() + pt.length_squared()) {
        return Err(at(
            sec.control.span().start,
            "the patch is degenerate: it has no normal at its centre".into(),
        ));
    }
    let centre = match &sec.centre {
        Some(c) => {
            let p = DVec3::from_array(*c.get_ref());
            if !p.is_finite() {
                return Err(at(c.span().start, "centre must be finite numbers".into()));
            }
            p
        }
        None => patch.centre(),
    };
    let positive = |v: &Option<Spanned<f64>>, name: &str, default: f64| match v {
        Some(x) if !(x.get_ref().is_finite() && *x.get_ref() > 0.0) => Err(at(
            x.span().start,
            format!("{name} must be a positive number (got {})", x.get_ref()),
        )),
        Some(x) => Ok(*x.get_ref()),
        None => Ok(default),
    };
    let radius = positive(&sec.radius, "radius", SAUCER_RADIUS)?;
    let height = positive(&sec.height, "height", SAUCER_HEIGHT)?;
    Ok(PatchBlend { patch, centre, radius, height })
}
