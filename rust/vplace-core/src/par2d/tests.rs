//! Tests of `par2d`: analytic values, the hard cases of issue 5, and the methods against each
//! other (`exact` against a 10^6-ray Monte Carlo within 4 standard errors, `par` against
//! `exact` to 1e-9 where its depth test is valid, and the straddling case where it is not).

use std::f64::consts::TAU;

use glam::DVec2;

use super::{Bounds2, Method, Scene2d};
use crate::error::VplaceError;
use crate::rng::Rng;

const WHITE: [f64; 3] = [1.0, 1.0, 1.0];
const BLACK: [f64; 3] = [0.0, 0.0, 0.0];

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<DVec2> {
    vec![
        DVec2::new(x0, y0),
        DVec2::new(x1, y0),
        DVec2::new(x1, y1),
        DVec2::new(x0, y1),
    ]
}

fn ngon(c: DVec2, r: f64, n: usize, rot: f64) -> Vec<DVec2> {
    (0..n)
        .map(|k| c + r * DVec2::from_angle(rot + TAU * k as f64 / n as f64))
        .collect()
}

fn at(scene: &Scene2d, p: DVec2, m: Method) -> f64 {
    scene.irradiance_at(p, m).unwrap()[0]
}

fn both(scene: &Scene2d, p: DVec2) -> (f64, f64) {
    (at(scene, p, Method::Par), at(scene, p, Method::Exact))
}

/// Asserts `exact` lies within 4 standard errors of a 10^6-ray Monte Carlo estimate. Where every
/// ray gave the same value (standard error 0), allows the value a miss probability of 5e-6.
fn assert_mc_agrees(scene: &Scene2d, p: DVec2, stream: u64) {
    let exact = scene.irradiance_at(p, Method::Exact).unwrap();
    let (mean, se) = scene.monte_carlo_at(p, 1_000_000, 17, stream).unwrap();
    for c in 0..3 {
        let tol = if se[c] > 0.0 { 4.0 * se[c] } else { 5e-6 };
        assert!(
            (exact[c] - mean[c]).abs() <= tol,
            "at {p:?} channel {c}: exact {} vs MC {} +- {}",
            exact[c],
            mean[c],
            se[c]
        );
    }
}

#[test]
fn par2d_single_light_analytic() {
    let scene = Scene2d::build(&[rect(2.0, -0.5, 3.0, 0.5)], &[[2.0, 1.0, 0.5]]).unwrap();
    let expected = 2.0 * 0.25f64.atan() / TAU;
    for m in [Method::Par, Method::Exact] {
        let e = scene.irradiance_at(DVec2::ZERO, m).unwrap();
        assert!((e[0] - 2.0 * expected).abs() < 1e-14, "{m:?} {e:?}");
        assert!((e[1] - expected).abs() < 1e-14);
        assert!((e[2] - 0.5 * expected).abs() < 1e-14);
    }
    assert_mc_agrees(&scene, DVec2::ZERO, 0);
}

#[test]
fn par2d_wrap_across_the_seam() {
    // The light straddles the -x axis (atan2's +-pi seam); the occluder starts exactly on it.
    let light = rect(-3.0, -0.5, -2.0, 0.5);
    let occ = rect(-1.5, 0.0, -1.0, 0.1);
    let expected = (2.0 * 0.25f64.atan() - 0.1f64.atan()) / TAU;
    for k in 0..64 {
        // Rotating the whole scene about the query point must not change anything.
        let rot = DVec2::from_angle(TAU * k as f64 / 64.0 + if k == 0 { 0.0 } else { 1e-3 });
        let r = |v: &Vec<DVec2>| v.iter().map(|&p| rot.rotate(p)).collect::<Vec<_>>();
        let scene = Scene2d::build(&[r(&light), r(&occ)], &[WHITE, BLACK]).unwrap();
        let (p, e) = both(&scene, DVec2::ZERO);
        assert!(
            (e - expected).abs() < 1e-14,
            "rotation {k}: exact {e} vs {expected}"
        );
        assert!(
            (p - expected).abs() < 1e-14,
            "rotation {k}: par {p} vs {expected}"
        );
    }
    let scene = Scene2d::build(&[light, occ], &[WHITE, BLACK]).unwrap();
    assert_mc_agrees(&scene, DVec2::ZERO, 1);
}

#[test]
fn par2d_points_on_edges_vertices_and_inside() {
    let scene = Scene2d::build(
        &[
            rect(0.0, 0.0, 1.0, 1.0),
            rect(2.0, 0.0, 3.0, 1.0),
            rect(0.5, 0.5, 1.5, 1.5),
        ],
        &[[3.0, 2.0, 1.0], BLACK, [1.0, 5.0, 0.0]],
    )
    .unwrap();
    let methods = [Method::Par, Method::Exact, Method::monte_carlo(64)];
    for m in methods {
        let e = |x: f64, y: f64| scene.irradiance_at(DVec2::new(x, y), m).unwrap();
        // Inside / on the edge / on a vertex of the first light only: its full emission.
        assert_eq!(e(0.25, 0.25), [3.0, 2.0, 1.0], "{m:?}");
        assert_eq!(e(0.0, 0.25), [3.0, 2.0, 1.0], "{m:?}");
        assert_eq!(e(1.0, 0.25), [3.0, 2.0, 1.0], "{m:?}");
        assert_eq!(e(0.0, 0.0), [3.0, 2.0, 1.0], "{m:?}");
        // In both lights: the componentwise maximum.
        assert_eq!(e(0.75, 0.75), [3.0, 5.0, 1.0], "{m:?}");
        // Inside, on an edge and on a vertex of the occluder: zero.
        assert_eq!(e(2.5, 0.5), BLACK, "{m:?}");
        assert_eq!(e(2.0, 0.5), BLACK, "{m:?}");
        assert_eq!(e(3.0, 1.0), BLACK, "{m:?}");
    }
    // Just outside a long light's edge the value tends to half the emission.
    let wall = Scene2d::build(&[rect(-1e3, -1.0, 1e3, 0.0)], &[WHITE]).unwrap();
    let (p, e) = both(&wall, DVec2::new(0.0, 1e-9));
    let expected = (2.0 * (1e3f64 / 1e-9).atan()) / TAU;
    assert!(
        (e - expected).abs() < 1e-12 && (p - expected).abs() < 1e-12,
        "{p} {e}"
    );
    assert!((e - 0.5).abs() < 1e-9);
}

#[test]
fn par2d_collinear_duplicate_vertices_and_orientation() {
    let clean = rect(2.0, -0.5, 3.0, 0.5);
    let messy = vec![
        DVec2::new(2.0, -0.5),
        DVec2::new(2.0, -0.5),
        DVec2::new(2.5, -0.5),
        DVec2::new(3.0, -0.5),
        DVec2::new(3.0, 0.5),
        DVec2::new(3.0, 0.5),
        DVec2::new(2.0, 0.5),
        DVec2::new(2.0, 0.0),
        DVec2::new(2.0, -0.5),
    ];
    let mut cw = clean.clone();
    cw.reverse();
    let occ = rect(1.0, -0.1, 1.2, 0.3);
    let reference = Scene2d::build(&[clean, occ.clone()], &[WHITE, BLACK]).unwrap();
    for poly in [messy, cw] {
        let s = Scene2d::build(&[poly, occ.clone()], &[WHITE, BLACK]).unwrap();
        assert_eq!(s.polygons()[0].vertices().len(), 4);
        for p in [DVec2::ZERO, DVec2::new(2.5, -2.0), DVec2::new(4.0, 0.1)] {
            for m in [Method::Par, Method::Exact] {
                assert_eq!(at(&s, p, m), at(&reference, p, m), "{p:?} {m:?}");
            }
        }
    }
}

#[test]
fn par2d_tiny_polygons() {
    // A right triangle of area 5e-13 at distance 1, and a 1 x 1e-12 sliver (area 1e-12).
    let h = 1e-6;
    let tri = vec![
        DVec2::new(1.0, 0.0),
        DVec2::new(1.0, h),
        DVec2::new(1.0 - h, 0.0),
    ];
    let scene = Scene2d::build(&[tri], &[WHITE]).unwrap();
    assert!((scene.polygons()[0].area() - 5e-13).abs() < 1e-9 * 5e-13);
    let expected = h.atan() / TAU;
    let (p, e) = both(&scene, DVec2::ZERO);
    assert!((e - expected).abs() < 1e-9 * expected && (p - e).abs() < 1e-9 * expected);
    assert_mc_agrees(&scene, DVec2::ZERO, 2);

    let sliver = rect(-0.5, 1.0, 0.5, 1.0 + 1e-12);
    let scene = Scene2d::build(std::slice::from_ref(&sliver), &[WHITE]).unwrap();
    let expected = 2.0 * 0.5f64.atan() / TAU;
    let (p, e) = both(&scene, DVec2::ZERO);
    assert!(
        (e - expected).abs() < 1e-12 && (p - expected).abs() < 1e-12,
        "{p} {e}"
    );
    // The sliver as an occluder in front of a light hides exactly its own interval.
    let scene = Scene2d::build(&[sliver, rect(-2.0, 2.0, 2.0, 3.0)], &[BLACK, WHITE]).unwrap();
    let expected = (2.0 * 1.0f64.atan() - 2.0 * 0.5f64.atan()) / TAU;
    let (p, e) = both(&scene, DVec2::ZERO);
    assert!(
        (e - expected).abs() < 1e-12 && (p - expected).abs() < 1e-12,
        "{p} {e}"
    );
    assert_mc_agrees(&scene, DVec2::ZERO, 3);
}

#[test]
fn par2d_large_coordinates_small_features() {
    // Features of 1e-3 around 1e6: ulp(1e6) / 1e-3 ~ 1.2e-7, so results agree with the scene
    // at the origin to ~1e-6 relative; par and exact see the same rounded input and agree to 1e-9.
    let base = [
        rect(2e-3, -0.5e-3, 3e-3, 0.5e-3),
        rect(1e-3, -0.1e-3, 1.2e-3, 0.3e-3),
        ngon(DVec2::new(-2e-3, 1e-3), 0.4e-3, 7, 0.3),
    ];
    let em = [WHITE, BLACK, [0.0, 2.0, 0.0]];
    let origin = Scene2d::build(&base, &em).unwrap();
    let shift = DVec2::new(1e6, -1e6);
    let moved: Vec<Vec<DVec2>> = base
        .iter()
        .map(|v| v.iter().map(|&p| p + shift).collect())
        .collect();
    let far = Scene2d::build(&moved, &em).unwrap();
    for q in [
        DVec2::ZERO,
        DVec2::new(0.5e-3, 1.5e-3),
        DVec2::new(-4e-3, -1e-3),
    ] {
        let a = origin.irradiance_at(q, Method::Exact).unwrap();
        let b = far.irradiance_at(q + shift, Method::Exact).unwrap();
        let c = far.irradiance_at(q + shift, Method::Par).unwrap();
        for k in 0..3 {
            assert!(
                (a[k] - b[k]).abs() <= 1e-6 * a[k].max(1e-3),
                "{q:?} {a:?} {b:?}"
            );
            assert!((b[k] - c[k]).abs() <= 1e-9, "{q:?} {b:?} {c:?}");
        }
        assert!(a[0] > 0.0 || a[1] > 0.0);
    }
}

#[test]
fn par2d_many_overlapping_occluders_union() {
    // 50 overlapping occluders in front of the light, all inside the angles (-0.05, 0.15) rad.
    let light = rect(2.0, -1.0, 2.5, 1.0);
    let mut polys = vec![light];
    let mut em = vec![WHITE];
    for k in 0..50 {
        let a0 = -0.05 + 0.004 * k as f64;
        let a1 = a0 + 0.0;
        let (lo, hi) = (a0.tan(), (a1 + 0.004 + 0.01).min(0.15).tan());
        polys.push(vec![
            DVec2::new(1.0, lo),
            DVec2::new(1.1, 1.1 * lo),
            DVec2::new(1.1, 1.1 * hi),
            DVec2::new(1.0, hi),
        ]);
        em.push(BLACK);
    }
    let scene = Scene2d::build(&polys, &em).unwrap();
    let expected = (2.0 * 0.5f64.atan() - 0.2) / TAU;
    let (p, e) = both(&scene, DVec2::ZERO);
    assert!(
        (e - expected).abs() < 1e-13 && (p - expected).abs() < 1e-13,
        "{p} {e} {expected}"
    );
    assert_mc_agrees(&scene, DVec2::ZERO, 4);
}

#[test]
fn par2d_touching_and_behind() {
    let light = rect(2.0, -0.5, 3.0, 0.5);
    let unoccluded = 2.0 * 0.25f64.atan() / TAU;
    // Touching the light's front face: blocks its own interval, +-atan(0.25 / 1.5).
    let front = rect(1.5, -0.25, 2.0, 0.25);
    // A triangle touching the front face with one vertex only.
    let tip = vec![
        DVec2::new(1.0, 0.1),
        DVec2::new(1.0, 0.2),
        DVec2::new(2.0, 0.15),
    ];
    // Touching the back face, and further behind: no effect.
    let back = rect(3.0, -0.25, 3.5, 0.25);
    let far = rect(4.0, -2.0, 5.0, 2.0);
    let cases = [
        (front, unoccluded - 2.0 * (0.25f64 / 1.5).atan() / TAU),
        (tip, unoccluded - (0.2f64.atan() - 0.075f64.atan()) / TAU),
        (back, unoccluded),
        (far, unoccluded),
    ];
    for (k, (occ, expected)) in cases.into_iter().enumerate() {
        let scene = Scene2d::build(&[light.clone(), occ], &[WHITE, BLACK]).unwrap();
        let (p, e) = both(&scene, DVec2::ZERO);
        assert!(
            (e - expected).abs() < 1e-14,
            "case {k}: exact {e} vs {expected}"
        );
        assert!(
            (p - expected).abs() < 1e-14,
            "case {k}: par {p} vs {expected}"
        );
        assert_mc_agrees(&scene, DVec2::ZERO, 10 + k as u64);
    }
}

/// The documented case where `par` is wrong: an occluder crossing the light like an X, in front
/// of it over the right half of its interval and behind it over the left half.
#[test]
fn par2d_straddling_occluder_par_is_wrong() {
    let bar = |y0: f64, y1: f64| {
        vec![
            DVec2::new(-1.0, y0 - 0.05),
            DVec2::new(1.0, y1 - 0.05),
            DVec2::new(1.0, y1 + 0.05),
            DVec2::new(-1.0, y0 + 0.05),
        ]
    };
    let light = bar(1.5, 2.5); // near on the left, far on the right
    let occ = bar(2.5, 1.5); // far on the left, near on the right
    let scene = Scene2d::build(&[light, occ], &[WHITE, BLACK]).unwrap();
    let p = DVec2::ZERO;
    let (par, exact) = both(&scene, p);
    let full = Scene2d::build(&[bar(1.5, 2.5)], &[WHITE]).unwrap();
    let unoccluded = at(&full, p, Method::Exact);
    // The truth: part of the light is visible, part is hidden.
    assert!(
        exact > 0.3 * unoccluded && exact < 0.7 * unoccluded,
        "{exact} {unoccluded}"
    );
    assert_mc_agrees(&scene, p, 20);
    // par blocks all or nothing of the overlap, so it misses by far more than rounding.
    assert!((par - exact).abs() > 0.2 * exact, "par {par} exact {exact}");
}

/// Random scenes where no polygon intersects a light (occluders overlap each other freely):
/// par's depth test is valid there and par matches exact to 1e-9.
#[test]
fn par2d_par_matches_exact_where_valid() {
    let mut rng = Rng::new(5, 0);
    let mut u = || f64::from(rng.next_f32());
    for scene_id in 0..20 {
        let mut polys = Vec::new();
        let mut em = Vec::new();
        let mut light_discs: Vec<(DVec2, f64)> = Vec::new();
        for _ in 0..4 {
            let c = DVec2::new(u() * 10.0 - 5.0, u() * 10.0 - 5.0);
            let r = 0.2 + u();
            if light_discs.iter().any(|&(d, s)| d.distance(c) < r + s) {
                continue;
            }
            light_discs.push((c, r));
            polys.push(ngon(c, r, 3 + (u() * 5.0) as usize, u() * TAU));
            em.push([u() + 0.1, u(), u()]);
        }
        let mut occluders = 0;
        while occluders < 12 {
            let c = DVec2::new(u() * 10.0 - 5.0, u() * 10.0 - 5.0);
            let r = 0.1 + 0.8 * u();
            if light_discs.iter().any(|&(d, s)| d.distance(c) < r + s) {
                continue;
            }
            polys.push(ngon(c, r, 3 + (u() * 6.0) as usize, u() * TAU));
            em.push(BLACK);
            occluders += 1;
        }
        let scene = Scene2d::build(&polys, &em).unwrap();
        for _ in 0..50 {
            let p = DVec2::new(u() * 12.0 - 6.0, u() * 12.0 - 6.0);
            let a = scene.irradiance_at(p, Method::Par).unwrap();
            let b = scene.irradiance_at(p, Method::Exact).unwrap();
            for c in 0..3 {
                assert!(
                    (a[c] - b[c]).abs() <= 1e-9,
                    "scene {scene_id} at {p:?}: {a:?} {b:?}"
                );
            }
        }
    }
}

/// exact against a 10^6-ray Monte Carlo at points of a scene with everything at once:
/// overlapping occluders, an occluder crossing a light, two overlapping lights, lights
/// shadowing each other.
#[test]
fn par2d_exact_matches_monte_carlo() {
    let polys = vec![
        rect(2.0, -0.5, 3.0, 0.5),
        ngon(DVec2::new(-2.0, 1.0), 0.7, 6, 0.2),
        rect(1.0, -0.2, 1.3, 0.1),
        rect(1.2, -0.1, 1.5, 0.4),
        vec![
            DVec2::new(-1.0, -1.0),
            DVec2::new(2.5, 0.8),
            DVec2::new(2.4, 1.0),
        ],
        ngon(DVec2::new(0.0, 2.5), 0.5, 5, 0.0),
        rect(2.4, -1.0, 2.6, 0.0),
        ngon(DVec2::new(-1.5, 1.3), 0.5, 4, 0.1),
    ];
    let em = [
        [1.0, 0.5, 0.0],
        [0.2, 0.2, 2.0],
        BLACK,
        BLACK,
        BLACK,
        [0.0, 1.0, 1.0],
        BLACK,
        [3.0, 0.0, 0.0],
    ];
    let scene = Scene2d::build(&polys, &em).unwrap();
    for (k, p) in [
        DVec2::ZERO,
        DVec2::new(0.5, -0.8),
        DVec2::new(-0.5, 1.5),
        DVec2::new(4.0, 0.0),
        DVec2::new(-3.5, -2.0),
        DVec2::new(1.8, 0.9),
    ]
    .into_iter()
    .enumerate()
    {
        assert_mc_agrees(&scene, p, 100 + k as u64);
    }
}

#[test]
fn par2d_light_map_matches_points_and_is_deterministic() {
    let scene = Scene2d::build(
        &[rect(2.0, -0.5, 3.0, 0.5), rect(1.0, -0.2, 1.3, 0.1)],
        &[WHITE, BLACK],
    )
    .unwrap();
    let bounds = Bounds2 {
        min: DVec2::new(-1.0, -2.0),
        max: DVec2::new(4.0, 2.0),
    };
    let (w, h) = (7, 5);
    for m in [
        Method::Exact,
        Method::Par,
        Method::MonteCarlo { rays: 32, seed: 9 },
    ] {
        let img = scene.light_map(bounds, w, h, m, None).unwrap();
        assert_eq!(img, scene.light_map(bounds, w, h, m, None).unwrap());
        let mut points = Vec::new();
        for row in 0..h {
            for col in 0..w {
                let x = -1.0 + (col as f64 + 0.5) / w as f64 * 5.0;
                let y = 2.0 - (row as f64 + 0.5) / h as f64 * 4.0;
                points.push(DVec2::new(x, y));
            }
        }
        let vals = scene.irradiance(&points, m, None).unwrap();
        let flat: Vec<f64> = vals.iter().flatten().copied().collect();
        assert_eq!(img, flat, "{m:?}");
    }
    let a = scene.light_map(bounds, w, h, Method::MonteCarlo { rays: 32, seed: 1 }, None);
    let b = scene.light_map(bounds, w, h, Method::MonteCarlo { rays: 32, seed: 2 }, None);
    assert_ne!(a.unwrap(), b.unwrap());
}

#[test]
fn par2d_bad_input_is_an_error() {
    let sq = rect(0.0, 0.0, 1.0, 1.0);
    let notch = vec![
        DVec2::new(0.0, 0.0),
        DVec2::new(2.0, 0.0),
        DVec2::new(1.0, 0.5),
        DVec2::new(2.0, 1.0),
        DVec2::new(0.0, 1.0),
    ];
    let star = ngon(DVec2::ZERO, 1.0, 5, 0.0);
    let star: Vec<DVec2> = (0..5).map(|k| star[(2 * k) % 5]).collect();
    let line = vec![DVec2::ZERO, DVec2::X, DVec2::new(2.0, 0.0)];
    assert!(matches!(
        Scene2d::build(&[], &[]),
        Err(VplaceError::Empty { .. })
    ));
    assert!(matches!(
        Scene2d::build(&[notch], &[WHITE]),
        Err(VplaceError::Invalid { .. })
    ));
    assert!(matches!(
        Scene2d::build(&[star], &[WHITE]),
        Err(VplaceError::Invalid { .. })
    ));
    assert!(matches!(
        Scene2d::build(&[line], &[WHITE]),
        Err(VplaceError::Invalid { .. })
    ));
    assert!(matches!(
        Scene2d::build(std::slice::from_ref(&sq), &[[1.0, -1.0, 0.0]]),
        Err(VplaceError::OutOfRange { .. })
    ));
    assert!(matches!(
        Scene2d::build(std::slice::from_ref(&sq), &[[f64::NAN, 0.0, 0.0]]),
        Err(VplaceError::NonFinite { .. })
    ));
    assert!(matches!(
        Scene2d::build(std::slice::from_ref(&sq), &[WHITE, WHITE]),
        Err(VplaceError::Shape { .. })
    ));
    let mut bad = sq.clone();
    bad[2].x = f64::INFINITY;
    assert!(matches!(
        Scene2d::build(&[bad], &[WHITE]),
        Err(VplaceError::NonFinite { .. })
    ));
    let s = Scene2d::build(&[sq], &[WHITE]).unwrap();
    assert!(matches!(
        s.irradiance_at(DVec2::new(f64::NAN, 0.0), Method::Exact),
        Err(VplaceError::NonFinite { .. })
    ));
    assert!(matches!(
        s.irradiance_at(DVec2::ZERO, Method::monte_carlo(0)),
        Err(VplaceError::OutOfRange { .. })
    ));
    let b = Bounds2 {
        min: DVec2::ONE,
        max: DVec2::ZERO,
    };
    assert!(matches!(
        s.light_map(b, 4, 4, Method::Exact, None),
        Err(VplaceError::Invalid { .. })
    ));
    let b = Bounds2 {
        min: DVec2::ZERO,
        max: DVec2::ONE,
    };
    assert!(matches!(
        s.light_map(b, 0, 4, Method::Exact, None),
        Err(VplaceError::OutOfRange { .. })
    ));
    let progress = crate::progress::Progress::default();
    progress
        .cancel
        .store(true, std::sync::atomic::Ordering::Relaxed);
    assert!(matches!(
        s.light_map(b, 4, 4, Method::Exact, Some(&progress)),
        Err(VplaceError::Cancelled)
    ));
}

/// The procedural scenes of the benches: lights and occluders overlap freely; exact agrees with
/// a 10^5-ray Monte Carlo within 4 standard errors, and the light map is finite and >= 0.
#[test]
fn par2d_procedural_scene() {
    let scene = super::procedural::random_scene(3, 40, 11).unwrap();
    assert_eq!((scene.len(), scene.light_count()), (43, 3));
    let mut rng = Rng::new(3, 1);
    for k in 0..8 {
        let p = DVec2::new(
            2.0 * f64::from(rng.next_f32()) - 1.0,
            2.0 * f64::from(rng.next_f32()) - 1.0,
        );
        let exact = scene.irradiance_at(p, Method::Exact).unwrap();
        let (mean, se) = scene.monte_carlo_at(p, 100_000, 5, k).unwrap();
        for c in 0..3 {
            // With no variance seen, allow a miss probability of 5e-5 times the brightest light.
            let tol = if se[c] > 0.0 { 4.0 * se[c] } else { 5e-5 * 2.0 };
            assert!(
                (exact[c] - mean[c]).abs() <= tol,
                "{p:?}: {exact:?} {mean:?} {se:?}"
            );
        }
    }
    let bounds = Bounds2 {
        min: DVec2::splat(-1.0),
        max: DVec2::splat(1.0),
    };
    let img = scene
        .light_map(bounds, 32, 32, Method::Exact, None)
        .unwrap();
    assert!(img.iter().all(|v| v.is_finite() && *v >= 0.0));
    assert!(img.iter().any(|v| *v > 0.0));
    assert!(super::procedural::random_scene(0, 0, 1).is_err());
}
