//! Axis-aligned boxes: the domain a polygonizer may visit.

use glam::DVec3;

/// An axis-aligned box `[min, max]`, closed on both sides.
///
/// Every polygonizer is bounded by one: a surface that runs out of it is cut there (and the
/// mesh is then open along the cut, which `skelform check` reports as boundary edges).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// The corner with the smallest coordinates; [`Aabb::new`] sorts the corners, a literal
    /// box should keep `min ≤ max` on every axis ([`Aabb::is_valid`] checks it).
    pub min: DVec3,
    /// The corner with the largest coordinates.
    pub max: DVec3,
}

impl Aabb {
    /// A box from two opposite corners, in any order.
    pub fn new(a: DVec3, b: DVec3) -> Self {
        Self { min: a.min(b), max: a.max(b) }
    }

    /// The cube `[-h, h]³`.
    pub fn cube(h: f64) -> Self {
        Self::new(DVec3::splat(-h), DVec3::splat(h))
    }

    /// The side lengths along x, y and z (negative on an axis where `max < min`).
    pub fn size(&self) -> DVec3 {
        self.max - self.min
    }

    /// The midpoint of the box: lattices are centred on it when the sides are not whole
    /// multiples of the cell.
    pub fn center(&self) -> DVec3 {
        (self.min + self.max) * 0.5
    }

    /// True when every side is finite and has positive length.
    pub fn is_valid(&self) -> bool {
        let s = self.size();
        self.min.is_finite() && self.max.is_finite() && s.x > 0.0 && s.y > 0.0 && s.z > 0.0
    }

    /// Whether `p` is in the box, faces included (a seed exactly on the domain's boundary is
    /// accepted). False for a NaN coordinate.
    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// The smallest box holding both.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb { min: self.min.min(other.min), max: self.max.max(other.max) }
    }

    /// The box grown by `d` on every side.
    pub fn inflate(&self, d: f64) -> Aabb {
        Aabb { min: self.min - DVec3::splat(d), max: self.max + DVec3::splat(d) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_in_any_order() {
        let b = Aabb::new(DVec3::new(1.0, -1.0, 2.0), DVec3::new(-1.0, 1.0, 0.0));
        assert_eq!(b.min, DVec3::new(-1.0, -1.0, 0.0));
        assert_eq!(b.max, DVec3::new(1.0, 1.0, 2.0));
        assert!(b.contains(DVec3::new(0.0, 0.0, 1.0)));
        assert!(!b.contains(DVec3::new(0.0, 0.0, 2.5)));
        assert!(b.is_valid());
        assert!(!Aabb::new(DVec3::ZERO, DVec3::new(1.0, 0.0, 1.0)).is_valid());
    }
}
