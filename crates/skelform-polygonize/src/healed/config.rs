//! The thesis's numbering of cube configurations, and ours.
//!
//! The thesis (Nguyen 2016, §4.2) lists the configurations it heals as 8-bit numbers, bit `i`
//! set when corner `i` is outside (`f > iso`), without saying how the corners are numbered.
//! Its three lists are exactly the orbits of 150, 92 and 90 under the 48 symmetries of the
//! cube and complement when the corners are numbered Bourke/Lorensen style (corner 0 at the
//! origin, 1–3 counter-clockwise around the bottom face, 4–7 above them), which the unit test
//! below checks. Our corner `c` sits at `(c & 1, c >> 1 & 1, c >> 2 & 1)` and our bit is set
//! for inside corners, so [`case_from_thesis`] renumbers and complements.

use std::collections::BTreeSet;

/// Corner positions in the thesis's (Bourke/Lorensen) order.
pub const THESIS_CORNERS: [[usize; 3]; 8] =
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]];

/// The thesis's class 10: two components, configurations (its numbering) 60 … 195.
pub const CLASS_10: [u8; 6] = [60, 85, 105, 150, 170, 195];
/// The thesis's class 12: two components.
pub const CLASS_12: [u8; 24] = [
    30, 45, 53, 58, 75, 83, 86, 89, 92, 101, 106, 120, 135, 149, 154, 163, 166, 169, 172, 180, 197,
    202, 210, 225,
];
/// The thesis's class 13: four components.
pub const CLASS_13: [u8; 2] = [90, 165];

/// The classes of the reduced marching-cubes table that the thesis heals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ThesisClass {
    /// Two opposite ambiguous faces (a self-intersection line straight through the cube).
    Ten,
    /// Two adjacent ambiguous faces (a line turning round an edge of the cube).
    Twelve,
    /// Six ambiguous faces (a triple point inside the cube).
    Thirteen,
}

fn our_corner(p: [usize; 3]) -> usize {
    p[0] | (p[1] << 1) | (p[2] << 2)
}

/// Our sign configuration (bit `c` set when our corner `c` is inside, `f < 0`) for a
/// configuration in the thesis's numbering (bit `i` set when its corner `i` is outside).
/// Samples exactly at the iso value are outside in both conventions.
pub fn case_from_thesis(config: u8) -> u8 {
    let mut case = 0u8;
    for (i, p) in THESIS_CORNERS.iter().enumerate() {
        if config & (1 << i) == 0 {
            case |= 1 << our_corner(*p);
        }
    }
    case
}

/// The thesis's number for one of our sign configurations.
pub fn thesis_from_case(case: u8) -> u8 {
    let mut config = 0u8;
    for (i, p) in THESIS_CORNERS.iter().enumerate() {
        if case & (1 << our_corner(*p)) == 0 {
            config |= 1 << i;
        }
    }
    config
}

/// Which healed class, if any, one of our sign configurations belongs to.
pub fn thesis_class(case: u8) -> Option<ThesisClass> {
    let config = thesis_from_case(case);
    if CLASS_10.contains(&config) {
        Some(ThesisClass::Ten)
    } else if CLASS_12.contains(&config) {
        Some(ThesisClass::Twelve)
    } else if CLASS_13.contains(&config) {
        Some(ThesisClass::Thirteen)
    } else {
        None
    }
}

/// The 48 symmetries of the cube (axis permutations and reflections) as permutations of the
/// thesis's corner numbers: `s[i]` is where corner `i` goes.
pub fn symmetries() -> Vec<[usize; 8]> {
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let index_of = |p: [usize; 3]| THESIS_CORNERS.iter().position(|&c| c == p).unwrap_or(0);
    let mut out = Vec::with_capacity(48);
    for perm in perms {
        for flips in 0..8usize {
            let mut s = [0usize; 8];
            for (i, c) in THESIS_CORNERS.iter().enumerate() {
                let q: [usize; 3] = std::array::from_fn(|a| c[perm[a]] ^ ((flips >> a) & 1));
                s[i] = index_of(q);
            }
            out.push(s);
        }
    }
    out
}

/// A configuration's orbit under the cube's symmetries and complement.
pub fn orbit(config: u8) -> BTreeSet<u8> {
    let mut out = BTreeSet::new();
    for s in symmetries() {
        let mut moved = 0u8;
        for (i, &to) in s.iter().enumerate() {
            if config & (1 << i) != 0 {
                moved |= 1 << to;
            }
        }
        out.insert(moved);
        out.insert(!moved);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::table::table;

    #[test]
    fn thesis_lists_are_the_orbits_of_150_92_90_in_bourke_order() {
        let set = |l: &[u8]| l.iter().copied().collect::<BTreeSet<u8>>();
        assert_eq!(symmetries().len(), 48);
        let distinct: BTreeSet<[usize; 8]> = symmetries().into_iter().collect();
        assert_eq!(distinct.len(), 48, "the 48 symmetries are distinct permutations");
        assert_eq!(orbit(150), set(&CLASS_10));
        assert_eq!(orbit(92), set(&CLASS_12));
        assert_eq!(orbit(90), set(&CLASS_13));
        assert_eq!((orbit(150).len(), orbit(92).len(), orbit(90).len()), (6, 24, 2));
        // The figure's examples are in their lists.
        assert!(CLASS_10.contains(&0b1001_0110) && CLASS_12.contains(&0b0101_1100));
        assert!(CLASS_13.contains(&0b0101_1010));
    }

    #[test]
    fn the_orbits_are_not_closed_under_other_corner_orders() {
        // With our own corner order read as the thesis's, the lists are not orbits: the
        // renumbering matters.
        let ours_as_thesis = |config: u8| {
            let mut c = 0u8;
            for i in 0..8 {
                if config & (1 << i) != 0 {
                    let p = [i & 1, (i >> 1) & 1, (i >> 2) & 1];
                    c |= 1 << THESIS_CORNERS.iter().position(|&q| q == p).unwrap();
                }
            }
            c
        };
        let moved: BTreeSet<u8> = CLASS_12.iter().map(|&c| ours_as_thesis(c)).collect();
        assert_ne!(moved, orbit(92));
    }

    #[test]
    fn renumbering_round_trips_and_matches_the_ambiguous_faces() {
        for case in 0..=255u8 {
            assert_eq!(case_from_thesis(thesis_from_case(case)), case);
        }
        let faces = |case: u8| table().ambiguous[case as usize];
        // Opposite faces are 2a and 2a + 1.
        let opposite_pair = |m: u8| (0..3).any(|a| m == 0b11 << (2 * a));
        for &c in &CLASS_10 {
            let m = faces(case_from_thesis(c));
            assert!(m.count_ones() == 2 && opposite_pair(m), "class 10 config {c}: faces {m:06b}");
            assert_eq!(thesis_class(case_from_thesis(c)), Some(ThesisClass::Ten));
        }
        for &c in &CLASS_12 {
            let m = faces(case_from_thesis(c));
            assert!(m.count_ones() == 2 && !opposite_pair(m), "class 12 config {c}: faces {m:06b}");
            assert_eq!(thesis_class(case_from_thesis(c)), Some(ThesisClass::Twelve));
        }
        for &c in &CLASS_13 {
            assert_eq!(faces(case_from_thesis(c)), 0b11_1111);
            assert_eq!(thesis_class(case_from_thesis(c)), Some(ThesisClass::Thirteen));
        }
        // Every other configuration with two or six ambiguous faces is one of these: the
        // thesis heals exactly the configurations whose faces can hold two or more
        // self-intersection points (class 7, with three, is left out by the thesis).
        let healed = (0..=255u8).filter(|&c| thesis_class(c).is_some()).count();
        let two_or_six = (0..=255u8).filter(|&c| matches!(faces(c).count_ones(), 2 | 6)).count();
        assert_eq!((healed, two_or_six), (32, 32));
    }
}
