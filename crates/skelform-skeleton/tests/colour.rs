//! Element colours blended into surface colours (DIS ch. 6): what `SkeletonField::colors`
//! gives near each element, between them, and across blend groups.

use glam::DVec3;
use skelform_field::Field;
use skelform_skeleton::{Blend, Element, GroupId, Kernel, Shape, Skeleton, SkeletonField};

const RED: [f64; 3] = [1.0, 0.0, 0.0];
const BLUE: [f64; 3] = [0.0, 0.0, 1.0];

/// A red segment on the left and a blue one on the right, end to end with a gap, so
/// their surfaces blend across the gap.
fn red_and_blue(blend: Blend) -> SkeletonField {
    let mut s = Skeleton::new();
    let seg = |a: f64, b: f64| {
        Shape::Segment(
            skelform_skeleton::Segment::new(DVec3::new(a, 0.0, 0.0), DVec3::new(b, 0.0, 0.0))
                .unwrap(),
        )
    };
    s.push(Element::new(seg(-1.0, -0.1), 0.2).unwrap().with_color(RED).unwrap()).unwrap();
    s.push(Element::new(seg(0.1, 1.0), 0.2).unwrap().with_color(BLUE).unwrap()).unwrap();
    SkeletonField::new(&s, blend).unwrap()
}

#[test]
fn red_near_the_red_element_blue_near_the_blue_and_a_blend_between() {
    for blend in [
        Blend::Convolution(Kernel::Gaussian),
        Blend::Convolution(Kernel::Wyvill),
        Blend::Sum(Kernel::Gaussian),
        Blend::SuperElliptic { range: 1.0, thumbweight: 2.0, angle_scaled: false },
    ] {
        let f = red_and_blue(blend);
        // Points on the surface above each element's middle, and above the gap.
        let pts =
            [DVec3::new(-0.6, 0.2, 0.0), DVec3::new(0.0, 0.15, 0.0), DVec3::new(0.6, 0.2, 0.0)];
        let c = f.colors(&pts).expect("the skeleton has colours");
        assert!(c[0][0] > 0.99 && c[0][2] < 0.01, "{blend:?}: left {:?}", c[0]);
        assert!(c[2][2] > 0.99 && c[2][0] < 0.01, "{blend:?}: right {:?}", c[2]);
        // Symmetric skeleton: the middle is half and half.
        assert!(
            (c[1][0] - 0.5).abs() < 1e-4 && (c[1][2] - 0.5).abs() < 1e-4,
            "{blend:?}: {:?}",
            c[1]
        );
        // Colours add up to one of each channel's weight: no green appears.
        assert!(c.iter().all(|c| c[1] == 0.0 && (c[0] + c[2] - 1.0).abs() < 1e-5));
        // Redness falls monotonically from left to right across the blend.
        let line: Vec<DVec3> =
            (0..=40).map(|i| DVec3::new(-0.5 + 0.025 * i as f64, 0.18, 0.0)).collect();
        let reds: Vec<f32> = f.colors(&line).unwrap().iter().map(|c| c[0]).collect();
        assert!(reds.windows(2).all(|w| w[1] <= w[0] + 1e-6), "{blend:?}: {reds:?}");
        assert!(reds[0] > 0.95 && reds[40] < 0.05, "{blend:?}: {reds:?}");
    }
}

#[test]
fn uncoloured_skeletons_have_no_colours_and_defaults_fill_in() {
    let mut s = Skeleton::new();
    s.add_point(DVec3::ZERO, 0.3, GroupId::DEFAULT).unwrap();
    let plain = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    assert!(plain.colors(&[DVec3::ZERO]).is_none());
    s.set_default_color([0.2, 0.4, 0.6]).unwrap();
    let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    let c = f.colors(&[DVec3::new(0.3, 0.0, 0.0), DVec3::new(9.0, 0.0, 0.0)]).unwrap();
    // On the surface and far beyond every element's reach (nearest element's colour).
    for c in c {
        assert!(
            (c[0] - 0.2).abs() < 1e-6 && (c[1] - 0.4).abs() < 1e-6 && (c[2] - 0.6).abs() < 1e-6
        );
    }
    assert!(s.set_default_color([1.5, 0.0, 0.0]).is_err());
    assert!(
        Element::new(Shape::Point(DVec3::ZERO), 0.1)
            .unwrap()
            .with_color([0.0, f64::NAN, 0.0])
            .is_err()
    );
}

#[test]
fn groups_that_do_not_blend_do_not_share_colours() {
    // Two parallel fingers, close, in groups that never blend: each keeps its colour even on
    // the side facing the other.
    let mut s = Skeleton::new();
    let a = s.add_group("a").unwrap();
    let b = s.add_group("b").unwrap();
    let i =
        s.add_segment(DVec3::new(0.0, -0.25, 0.0), DVec3::new(1.0, -0.25, 0.0), 0.2, a).unwrap();
    let j = s.add_segment(DVec3::new(0.0, 0.25, 0.0), DVec3::new(1.0, 0.25, 0.0), 0.2, b).unwrap();
    s.set_color(i, RED).unwrap();
    s.set_color(j, BLUE).unwrap();
    let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    // Just inside each finger's surface, on the side facing the other.
    let pa = DVec3::new(0.5, -0.06, 0.0);
    let pb = DVec3::new(0.5, 0.06, 0.0);
    assert!(f.eval(pa) < 0.0 && f.eval(pb) < 0.0);
    let c = f.colors(&[pa, pb]).unwrap();
    assert_eq!(c[0], [1.0, 0.0, 0.0]);
    assert_eq!(c[1], [0.0, 0.0, 1.0]);
    // Had they blended, the facing sides would have mixed.
    let mut one = s.clone();
    one.blend_groups(a, b).unwrap();
    let g = SkeletonField::new(&one, Blend::Convolution(Kernel::Gaussian)).unwrap();
    let mixed = g.colors(&[pa]).unwrap()[0];
    assert!(mixed[2] > 0.05, "{mixed:?}");
}
