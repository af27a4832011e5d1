//! What the pictures must show: a sphere as a disc of the size the camera model predicts,
//! light where the light is, region colours in proportion to what is visible, curves where
//! they project and not where the surface hides them, the same pixels on any thread count,
//! and clear errors for bad input.

mod common;

use common::*;
use skelform_mesh::{Mesh, RegionPair};
use skelform_render::{Projection, RenderError, Renderer, Settings, View, render, write_apng};

/// Flat light: every pixel of a surface is exactly its colour.
fn flat(s: Settings) -> Settings {
    Settings {
        light: skelform_render::Light {
            ambient: 1.0,
            diffuse: 0.0,
            specular: 0.0,
            ..Default::default()
        },
        ..s
    }
}

fn small() -> Settings {
    Settings { width: 200, height: 160, supersample: 1, ..Settings::default() }
}

fn count(img: &skelform_render::Image, c: [u8; 3]) -> usize {
    img.pixels.iter().filter(|p| **p == c).count()
}

fn top() -> View {
    View { azimuth: 0.0, elevation: 90.0 }
}

#[test]
fn icosphere_is_closed_and_outward() {
    let r = skelform_mesh::check::check(&icosphere(3, [0.0; 3], 1.0));
    assert!(r.is_closed_manifold());
    assert_eq!(r.outward, Some(true));
}

#[test]
fn a_sphere_is_a_disc_of_the_expected_radius() {
    let sphere = icosphere(5, [0.0; 3], 1.0);
    for projection in [
        Projection::default(),
        Projection::Perspective { fov_degrees: 60.0 },
        Projection::Orthographic,
    ] {
        for view in [View::default(), View { azimuth: -70.0, elevation: -40.0 }] {
            let s = Settings { projection, view, ..small() };
            let renderer = Renderer::new(&sphere).unwrap();
            let cam = renderer.camera(&s);
            // The silhouette of a sphere of radius R centred on the axis at distance d is a
            // circle of radius f·tan(asin(R/d)) = f·R/√(d² − R²) pixels (perspective), or
            // scale·R (orthographic).
            let expected = match projection {
                Projection::Perspective { .. } => {
                    let d = cam.distance;
                    cam.focal_px() / (d * d - 1.0).sqrt()
                }
                Projection::Orthographic => cam.scale,
            };
            let img = renderer.render(&s).unwrap();
            let covered = img.pixels.len() - count(&img, s.background);
            let by_area = (covered as f64 / std::f64::consts::PI).sqrt();
            assert!(
                (by_area - expected).abs() < 2.0,
                "{projection:?} {view:?}: area radius {by_area}, expected {expected}"
            );
            // The middle row: the run of surface pixels is a diameter.
            let row: Vec<bool> =
                (0..s.width).map(|x| img.pixel(x, s.height / 2) != s.background).collect();
            let first = row.iter().position(|&b| b).unwrap() as f64;
            let last = row.iter().rposition(|&b| b).unwrap() as f64;
            let diameter = last - first + 1.0;
            assert!(
                (diameter / 2.0 - expected).abs() < 2.0,
                "{projection:?}: row radius {}, expected {expected}",
                diameter / 2.0
            );
            let centre = (first + last + 1.0) / 2.0;
            assert!((centre - s.width as f64 / 2.0).abs() < 1.0, "the disc is centred");
        }
    }
}

#[test]
fn shading_is_brighter_towards_the_light() {
    let sphere = icosphere(5, [0.0; 3], 1.0);
    let s = Settings { width: 240, height: 240, ..Settings::default() };
    let renderer = Renderer::new(&sphere).unwrap();
    let cam = renderer.camera(&s);
    let r = cam.focal_px() / (cam.distance * cam.distance - 1.0).sqrt();
    let img = renderer.render(&s).unwrap();
    // The light is up and to the left in camera space: up is −y in the image.
    let l = s.light.direction;
    let len = (l[0] * l[0] + l[1] * l[1]).sqrt() as f64;
    let (dx, dy) = (l[0] as f64 / len, -l[1] as f64 / len);
    let at = |t: f64| {
        let (x, y) = (120.0 + t * r * dx, 120.0 + t * r * dy);
        brightness(img.pixel(x as u32, y as u32))
    };
    assert!(at(0.5) > at(0.0) + 10.0, "towards the light {} vs centre {}", at(0.5), at(0.0));
    assert!(at(0.0) > at(-0.5) + 10.0, "centre {} vs away {}", at(0.0), at(-0.5));
    assert!(at(-0.9) < at(0.9));
    // Moving the light to the other side swaps them.
    let mut s2 = s.clone();
    s2.light.direction = [-l[0], -l[1], l[2]];
    let img2 = renderer.render(&s2).unwrap();
    let at2 = |t: f64| {
        let (x, y) = (120.0 + t * r * dx, 120.0 + t * r * dy);
        brightness(img2.pixel(x as u32, y as u32))
    };
    assert!(at2(-0.5) > at2(0.5));
}

#[test]
fn background_where_there_is_no_surface() {
    let sphere = icosphere(4, [0.0; 3], 1.0);
    let s = Settings { width: 120, height: 90, ..Settings::default() };
    let renderer = Renderer::new(&sphere).unwrap();
    let cam = renderer.camera(&s);
    let r = cam.focal_px() / (cam.distance * cam.distance - 1.0).sqrt();
    let img = renderer.render(&s).unwrap();
    for y in 0..s.height {
        for x in 0..s.width {
            let (dx, dy) = (x as f64 + 0.5 - 60.0, y as f64 + 0.5 - 45.0);
            let d = (dx * dx + dy * dy).sqrt();
            if d > r + 1.5 {
                assert_eq!(img.pixel(x, y), s.background, "({x}, {y}) outside the disc");
            } else if d < r - 1.5 {
                assert_ne!(img.pixel(x, y), s.background, "({x}, {y}) inside the disc");
            }
        }
    }
}

#[test]
fn region_colours_appear_in_proportion_to_visible_area() {
    // 14 of 20 columns are (1, 2): 70 % of the square.
    let square = split_square(20, 14);
    for projection in [Projection::default(), Projection::Orthographic] {
        let s = flat(Settings { view: top(), projection, legend: false, curves: false, ..small() });
        let renderer = Renderer::new(&square).unwrap();
        let colours = renderer.region_colours(&s);
        assert_eq!(
            colours.iter().map(|c| c.0).collect::<Vec<_>>(),
            vec![RegionPair(1, 2), RegionPair(1, 3)]
        );
        let img = renderer.render(&s).unwrap();
        let a = count(&img, colours[0].1) as f64;
        let b = count(&img, colours[1].1) as f64;
        let covered = (img.pixels.len() - count(&img, s.background)) as f64;
        assert_eq!(a + b, covered, "every surface pixel has one of the two colours");
        assert!((a / (a + b) - 0.7).abs() < 0.01, "{projection:?}: {a} and {b}");
    }
    // From the side only part of the square is visible, but the proportion of the columns
    // is kept by the parallel projection along y.
    let s = flat(Settings {
        view: View { azimuth: 0.0, elevation: 40.0 },
        projection: Projection::Orthographic,
        legend: false,
        curves: false,
        ..small()
    });
    let renderer = Renderer::new(&square).unwrap();
    let colours = renderer.region_colours(&s);
    let img = renderer.render(&s).unwrap();
    let (a, b) = (count(&img, colours[0].1) as f64, count(&img, colours[1].1) as f64);
    assert!((a / (a + b) - 0.7).abs() < 0.015, "{a} and {b}");
    // An explicit colour for one pair replaces the palette's.
    let s = Settings { region_colours: vec![(RegionPair(1, 3), [255, 0, 0])], ..s };
    let img = renderer.render(&s).unwrap();
    assert_eq!(count(&img, [255, 0, 0]) as f64, b);
}

#[test]
fn a_legend_names_the_regions() {
    let square = split_square(8, 3);
    let s = Settings { view: top(), legend: true, ..small() };
    let with = render(&square, &s).unwrap();
    let without = render(&square, &Settings { legend: false, ..s.clone() }).unwrap();
    // The legend sits in the top-left corner: the two pictures differ there, and only there.
    let differ: Vec<(u32, u32)> = (0..s.height)
        .flat_map(|y| (0..s.width).map(move |x| (x, y)))
        .filter(|&(x, y)| with.pixel(x, y) != without.pixel(x, y))
        .collect();
    assert!(!differ.is_empty());
    assert!(differ.iter().all(|&(x, y)| x < s.width / 2 && y < s.height / 2));
    // Its swatches carry the region colours.
    let renderer = Renderer::new(&square).unwrap();
    for (_, c) in renderer.region_colours(&s) {
        assert!(count(&with, c) > count(&without, c), "swatch of {c:?}");
    }
}

#[test]
fn curves_are_drawn_where_they_project() {
    let square = split_square(20, 14); // the curve runs along x = 0.4
    for projection in [Projection::default(), Projection::Orthographic] {
        let s = flat(Settings { view: top(), projection, legend: false, ..small() });
        let renderer = Renderer::new(&square).unwrap();
        let cam = renderer.camera(&s);
        let img = renderer.render(&s).unwrap();
        let mut on = 0;
        for k in 1..20 {
            let y = -1.0 + 2.0 * k as f64 / 20.0;
            let [px, py, _] = cam.project([0.4, y, 0.0]).unwrap();
            let (x, yy) = (px.floor() as u32, py.floor() as u32);
            if img.pixel(x, yy) == s.curve_colour {
                on += 1;
            }
            // Three pixels wide: well to either side is the surface.
            assert_ne!(img.pixel(x + 5, yy), s.curve_colour);
            assert_ne!(img.pixel(x - 5, yy), s.curve_colour);
        }
        assert_eq!(on, 19, "{projection:?}");
        // Without curves there is no curve colour at all.
        let img = renderer.render(&Settings { curves: false, ..s.clone() }).unwrap();
        assert_eq!(count(&img, s.curve_colour), 0);
    }
}

#[test]
fn curves_behind_the_surface_are_hidden() {
    // A ball above the middle of the curve, between it and the camera looking down.
    let ball = labelled(icosphere(4, [0.4, 0.0, 0.6], 0.3), RegionPair(4, 5));
    let mesh = merge(split_square(20, 14), &ball);
    let s = flat(Settings {
        view: top(),
        projection: Projection::Orthographic,
        legend: false,
        ..small()
    });
    let renderer = Renderer::new(&mesh).unwrap();
    let cam = renderer.camera(&s);
    let img = renderer.render(&s).unwrap();
    let pixel_at = |y: f64| {
        let [px, py, _] = cam.project([0.4, y, 0.0]).unwrap();
        img.pixel(px as u32, py as u32)
    };
    let ball_colour = renderer.region_colours(&s)[2].1;
    assert_eq!(pixel_at(0.0), ball_colour, "the ball hides the curve");
    assert_eq!(pixel_at(0.1), ball_colour);
    assert_eq!(pixel_at(0.6), s.curve_colour, "beyond the ball the curve shows");
    assert_eq!(pixel_at(-0.6), s.curve_colour);
    // Seen through a transparent ball, the hidden part shows faintly: neither the ball's
    // colour nor the full curve colour.
    let t = Settings { transparent: true, ..s.clone() };
    let img = renderer.render(&t).unwrap();
    let [px, py, _] = cam.project([0.4, 0.0, 0.0]).unwrap();
    let p = img.pixel(px as u32, py as u32);
    assert_ne!(p, s.curve_colour);
    let [qx, qy, _] = cam.project([0.4, 0.6, 0.0]).unwrap();
    assert_eq!(img.pixel(qx as u32, qy as u32), s.curve_colour);
}

#[test]
fn transparency_shows_inner_sheets() {
    let outer = labelled(icosphere(4, [0.0; 3], 1.0), RegionPair(1, 2));
    let inner = labelled(icosphere(4, [0.0; 3], 0.5), RegionPair(2, 3));
    let mesh = merge(outer, &inner);
    let s = flat(Settings { legend: false, ..small() });
    let renderer = Renderer::new(&mesh).unwrap();
    let colours = renderer.region_colours(&s);
    let (outer_c, inner_c) = (colours[0].1, colours[1].1);
    let opaque = renderer.render(&s).unwrap();
    let centre = (s.width / 2, s.height / 2);
    assert_eq!(opaque.pixel(centre.0, centre.1), outer_c);
    assert_eq!(count(&opaque, inner_c), 0, "opaque: the inner sphere is hidden");
    let see = renderer.render(&Settings { transparent: true, ..s.clone() }).unwrap();
    let dist =
        |a: [u8; 3], b: [u8; 3]| (0..3).map(|k| (a[k] as f64 - b[k] as f64).powi(2)).sum::<f64>();
    let p = see.pixel(centre.0, centre.1);
    assert!(dist(p, inner_c) < dist(outer_c, inner_c), "{p:?} leans to the inner colour");
    // Where only the outer sphere is (between the radii) the inner colour has no say, and
    // there is no seam: the picture there is smooth, every pixel alike.
    let ring: Vec<[u8; 3]> = (0..8)
        .map(|k| {
            let a = k as f64 * std::f64::consts::PI / 4.0;
            let cam = renderer.camera(&s);
            let r = cam.focal_px() / (cam.distance * cam.distance - 1.0).sqrt() * 0.8;
            see.pixel(
                (centre.0 as f64 + r * a.cos()) as u32,
                (centre.1 as f64 + r * a.sin()) as u32,
            )
        })
        .collect();
    for p in &ring {
        assert!(dist(*p, ring[0]) < 30.0, "{ring:?}");
    }
}

#[test]
fn no_seams_in_a_transparent_plane() {
    // A finely split plane seen at a slant: with exact coverage every pixel inside it is
    // covered by exactly one triangle, so a transparent plane is one even tone (in parallel
    // projection, where it meets every ray at the same angle).
    let square = split_square(37, 37);
    let s = flat(Settings {
        view: View { azimuth: 13.0, elevation: 61.0 },
        projection: Projection::Orthographic,
        legend: false,
        curves: false,
        transparent: true,
        ..small()
    });
    let img = render(&square, &s).unwrap();
    let mut tones: Vec<[u8; 3]> =
        img.pixels.iter().copied().filter(|p| *p != s.background).collect();
    tones.sort();
    tones.dedup();
    assert_eq!(tones.len(), 1, "{} tones", tones.len());
}

#[test]
fn wireframe_draws_edges() {
    let square = split_square(4, 2);
    let s = flat(Settings { view: top(), legend: false, curves: false, ..small() });
    let plain = render(&square, &s).unwrap();
    let wired = render(&square, &Settings { wireframe: true, ..s.clone() }).unwrap();
    // 5 horizontal, 5 vertical and 16 diagonal lines of about one pixel, darker than the
    // surface under them.
    let mut changed = 0;
    for (a, b) in plain.pixels.iter().zip(&wired.pixels) {
        if a != b {
            changed += 1;
            assert!(brightness(*b) < brightness(*a));
        }
    }
    assert!(changed > 10 * 100, "{changed}");
    // Along a grid line every pixel is darkened.
    let cam = Renderer::new(&square).unwrap().camera(&s);
    for k in 1..20 {
        let [x, y, _] = cam.project([0.0, -1.0 + k as f64 / 10.0, 0.0]).unwrap();
        let (x, y) = (x.round() as u32, y as u32);
        // The line lies between the centres of pixels x − 1 and x.
        let darkening = |x: u32| brightness(plain.pixel(x, y)) - brightness(wired.pixel(x, y));
        assert!(darkening(x - 1) + darkening(x) > 30.0, "at ({x}, {y})");
    }
}

#[test]
fn same_pixels_on_any_thread_count() {
    let ball = labelled(icosphere(5, [0.3, 0.1, 0.4], 0.45), RegionPair(2, 3));
    let mesh = merge(split_square(60, 25), &ball);
    let variants = [
        Settings { width: 203, height: 151, ..Settings::default() },
        Settings {
            width: 203,
            height: 151,
            transparent: true,
            wireframe: true,
            ..Settings::default()
        },
        Settings {
            width: 97,
            height: 131,
            supersample: 3,
            projection: Projection::Orthographic,
            ..Settings::default()
        },
    ];
    for s in variants {
        let images: Vec<Vec<u8>> = [1, 2, 4]
            .iter()
            .map(|&n| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
                pool.install(|| render(&mesh, &s).unwrap()).encode_png().unwrap()
            })
            .collect();
        assert_eq!(images[0], images[1]);
        assert_eq!(images[0], images[2]);
    }
}

#[test]
fn turntables_turn_at_a_fixed_distance() {
    let square = split_square(10, 4);
    let s = flat(Settings {
        width: 80,
        height: 60,
        view: View { azimuth: 0.0, elevation: 30.0 },
        legend: false,
        ..Settings::default()
    });
    let r = Renderer::new(&square).unwrap();
    let frames = r.turntable(&s, 4).unwrap();
    assert_eq!(frames.len(), 4);
    assert_ne!(frames[0], frames[1]);
    // The square is symmetric under a half turn about z, except for its labels: the
    // half-turn frame covers the same pixels as the first (up to rounding at the edges).
    let mask = |i: &skelform_render::Image| {
        i.pixels.iter().map(|p| *p != s.background).collect::<Vec<_>>()
    };
    let (m0, m2) = (mask(&frames[0]), mask(&frames[2]));
    let differ = m0.iter().zip(&m2).filter(|(a, b)| a != b).count();
    let covered = m0.iter().filter(|a| **a).count();
    assert!(covered > 1000 && differ < 20, "{covered} covered, {differ} differ");
    // The half turn swaps the sides: the colour on the left of the first frame is on the
    // right of the third.
    assert_eq!(frames[0].pixel(20, 40), frames[2].pixel(60, 40));
    assert_ne!(frames[0].pixel(20, 40), frames[0].pixel(60, 40));
    assert!(matches!(r.turntable(&s, 0), Err(RenderError::Settings(_))));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("turn.png");
    write_apng(&path, &frames, 100).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert!(bytes.windows(4).any(|w| w == b"acTL"), "an animated PNG");
    // Drawn and encoded a frame at a time, the same file (what `render --turntable` writes,
    // holding one frame however many there are).
    let streamed = dir.path().join("streamed.png");
    r.write_turntable(&s, 4, 100, &streamed).unwrap();
    assert_eq!(std::fs::read(&streamed).unwrap(), bytes);
    assert!(r.write_turntable(&s, 0, 100, &streamed).is_err());
}

#[test]
fn bad_input_gives_clear_errors() {
    let sphere = icosphere(1, [0.0; 3], 1.0);
    let e = render(&sphere, &Settings { width: 0, ..Settings::default() }).unwrap_err();
    assert!(matches!(e, RenderError::EmptyImage { .. }));
    assert_eq!(e.to_string(), "the image size 0×600 is empty: width and height must be at least 1");
    let e = render(&sphere, &Settings { height: 100_000, ..Settings::default() }).unwrap_err();
    assert!(matches!(e, RenderError::TooLarge { .. }), "{e}");
    let e = render(&Mesh::default(), &Settings::default()).unwrap_err();
    assert!(matches!(e, RenderError::NoTriangles));
    assert_eq!(e.to_string(), "the mesh has no triangles to draw");
    let mut broken = sphere.clone();
    broken.triangles.push([0, 1, 9999]);
    let e = render(&broken, &Settings::default()).unwrap_err();
    assert!(matches!(e, RenderError::InvalidMesh(_)), "{e}");
    let mut nan = sphere.clone();
    nan.positions[3][1] = f32::NAN;
    let e = render(&nan, &Settings::default()).unwrap_err();
    assert!(e.to_string().contains("vertex 3"), "{e}");
    for bad in [
        Settings { supersample: 0, ..Settings::default() },
        Settings { opacity: 0.0, ..Settings::default() },
        Settings { view: View { azimuth: f64::NAN, elevation: 0.0 }, ..Settings::default() },
        Settings { view: View { azimuth: 0.0, elevation: 95.0 }, ..Settings::default() },
        Settings {
            projection: Projection::Perspective { fov_degrees: 180.0 },
            ..Settings::default()
        },
        Settings { curve_width: -1.0, ..Settings::default() },
        Settings { fit: Some(([0.0; 3], [1.0, f32::NAN, 1.0])), ..Settings::default() },
        Settings { fit: Some(([1.0; 3], [0.0; 3])), ..Settings::default() },
    ] {
        assert!(matches!(render(&sphere, &bad), Err(RenderError::Settings(_))), "{bad:?}");
    }
}

#[test]
fn pngs_are_written_whole_or_not_at_all() {
    let img = render(
        &icosphere(2, [0.0; 3], 1.0),
        &Settings { width: 40, height: 30, ..Settings::default() },
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ball.png");
    img.write_png(&path).unwrap();
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (40, 30));
    assert_eq!(&buf[..info.buffer_size()], &img.as_bytes()[..]);
    let names: Vec<_> =
        std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names, vec![std::ffi::OsString::from("ball.png")], "no temporary file is left");
    let e = img.write_png(&dir.path().join("missing/ball.png")).unwrap_err();
    assert!(e.to_string().starts_with("cannot write "), "{e}");
}

#[test]
fn vertex_colours_shade_the_picture() {
    // A sphere red on its left half (x < 0) and blue on its right, seen from above in flat
    // light: left pixels red, right pixels blue, in proportion; off, the surface colour.
    let mut sphere = icosphere(4, [0.0; 3], 1.0);
    sphere.colors = sphere
        .positions
        .iter()
        .map(|p| if p[0] < 0.0 { [1.0, 0.0, 0.0] } else { [0.0, 0.0, 1.0] })
        .collect();
    let s = flat(Settings { view: top(), legend: false, ..small() });
    let img = render(&sphere, &s).unwrap();
    let (red, blue) = (count(&img, [255, 0, 0]), count(&img, [0, 0, 255]));
    assert!(red > 3000 && blue > 3000, "red {red}, blue {blue}");
    assert!((red as f64 / blue as f64 - 1.0).abs() < 0.1, "red {red}, blue {blue}");
    // Red pixels lie left of the image's centre, blue right (x grows to the right in a
    // view from above at azimuth 0).
    let w = img.width as usize;
    let mean_x = |c: [u8; 3]| {
        let xs: Vec<usize> =
            img.pixels.iter().enumerate().filter(|(_, p)| **p == c).map(|(i, _)| i % w).collect();
        xs.iter().sum::<usize>() as f64 / xs.len() as f64
    };
    assert!(mean_x([255, 0, 0]) < w as f64 / 2.0 && mean_x([0, 0, 255]) > w as f64 / 2.0);
    // Turned off, the plain surface colour again.
    let plain = render(&sphere, &Settings { vertex_colours: false, ..s.clone() }).unwrap();
    assert_eq!(count(&plain, [255, 0, 0]) + count(&plain, [0, 0, 255]), 0);
    assert!(count(&plain, s.surface) > 6000);
    // Labelled (the leaf's regions, painted with its texture): still its colours, not the
    // region colours, and the legend has no region swatches to show.
    let mut labelled = sphere.clone();
    labelled.labels = labelled
        .triangles
        .iter()
        .map(|t| {
            if sphere.positions[t[0] as usize][1] < 0.0 {
                RegionPair(0, 1)
            } else {
                RegionPair(1, 2)
            }
        })
        .collect();
    let img = render(&labelled, &s).unwrap();
    assert_eq!((count(&img, [255, 0, 0]), count(&img, [0, 0, 255])), (red, blue));
    let with_legend = Settings { legend: true, ..s.clone() };
    assert_eq!(render(&labelled, &with_legend).unwrap(), img);
    labelled.colors.clear();
    assert_ne!(render(&labelled, &with_legend).unwrap(), render(&labelled, &s).unwrap());
}
