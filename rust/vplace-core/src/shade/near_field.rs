//! The short-range light a VPL set cannot carry, gathered from the view's own pixels.
//!
//! A VPL lights a receiver through the cosine at the VPL, and a receiver beside the VPL's
//! surface sees it at grazing angles: a point in a room's corner gets almost nothing from the
//! VPLs on the wall beside it, where the light path tracer finds the adjacent wall filling half
//! its hemisphere. Below the set's spacing the VPLs cannot carry that light, whatever their
//! powers. Gathered here instead: for each covered pixel `x`, the light reflected towards it by
//! the surfaces the view shows within `distance` of it,
//!
//! `E(x) = sum_y L(y) cos(x) cos(y) A(y) / r^2`, added as `albedo(x) / pi * E(x)`,
//!
//! over the pixels `y` of a window around `x`, with `A(y)` the surface area the pixel covers
//! (from the world positions of its neighbours; each pixel taken as a disk of that area, so that
//! `A / r^2` becomes `A / (r^2 + A / pi)`, and the samples' projected solid angle held to `pi`:
//! two surfaces in contact, as a curtain on a floor, would otherwise gather without bound) and
//! `L(y)` its diffuse radiance: the captured direct light (`albedo * diffuse_direct`, never
//! emission) plus the VPLs' own. A shadow ray between the two surfaces drops what the pixel
//! does not see (on Sponza's main view, without it, the hems of the curtains gathered the sunlit
//! floor in front of them through the cloth: RMSE .0296 against .0197 with it); pixels whose
//! normals average two surfaces neither gather nor give.
//!
//! This is the light EEVEE's horizon scan gives when, with ray tracing on, its fast GI gathers
//! global illumination within the same distance: a screen-space gather of the surfaces on
//! screen. Measured on the L room's back view (EEVEE, no VPLs, 192 x 108): the fast GI's light
//! and this gather have the same mean to 1 % and correlate at .86 per pixel. The add-on's
//! pipeline gives a set the gather where its captures show it helps, and has EEVEE's fast GI
//! add it (ARCHITECTURE.md, "Near-field light gathered from the view": where VPLs are dense, as
//! on Sponza's sunlit floor, it counts their light a second time, and the captures leave it
//! out there).
//!
//! The distance is [`gather_distance`]: half the median near-field radius of the set, below
//! which its VPLs no longer resolve the light between surfaces.

use glam::{Vec3, Vec3A};
use obvhs::ray::Ray;
use rayon::prelude::*;

use crate::error::{Result, VplaceError};
use crate::scene::Scene;
use crate::view::View;

/// The most window samples on each side of a pixel; where the distance spans more pixels, the
/// window takes every `k`-th pixel and each sample stands for `k x k` of them.
pub const GATHER_HALF_WINDOW: usize = 16;

/// The half-width of the core of the window, in pixels, where every pixel is sampled whatever
/// the stride: a pixel next to a corner takes most of its light from the first few pixels
/// across it.
const DENSE_CORE: isize = 4;

/// The shortest shading normal of a pixel that gathers or gives near-field light: shorter ones
/// average two surfaces (a pixel on an edge).
const MIN_NORMAL: f32 = 0.9;

/// The gather distance in multiples of the set's median near-field radius. Measured with the
/// VPLs' radii of the built-in rooms (256 VPLs, 4 seeds, `vplace+refit`): at the median radius
/// the Cornell box lost up to .001 SSIM and Sponza's RMSE doubled on two views (light gathered
/// twice where the VPLs' disks already carry it); at half of it every view of the L, sky and
/// panel rooms gained, and the Cornell box's moved by -.0004 to +.0008.
pub const GATHER_RADIUS_FACTOR: f32 = 0.5;

/// The gather distance of a set whose near-field radii are `radii` (see
/// [`crate::vpl::near_field_radii`]): [`GATHER_RADIUS_FACTOR`] times their median, 0 for an
/// empty set.
#[must_use]
pub fn gather_distance(radii: &[f32]) -> f32 {
    let mut r: Vec<f32> = radii.iter().copied().filter(|v| v.is_finite()).collect();
    if r.is_empty() {
        return 0.0;
    }
    r.sort_by(f32::total_cmp);
    GATHER_RADIUS_FACTOR * r[r.len() / 2]
}

fn at(a: &[f32], i: usize) -> Vec3 {
    Vec3::new(a[3 * i], a[3 * i + 1], a[3 * i + 2])
}

/// The world-space steps to the pixel's neighbours along x and y: of the two on each axis the
/// shorter (a step across a depth edge would be long), zero where neither is covered.
fn steps(view: &View, x: usize, y: usize) -> (Vec3, Vec3) {
    let (w, h) = (view.width, view.height);
    let i = y * w + x;
    let p = at(&view.position, i);
    let pick = |a: Option<usize>, b: Option<usize>| -> Vec3 {
        let d = |j: Option<usize>| {
            j.filter(|&j| view.covered[j])
                .map(|j| at(&view.position, j) - p)
        };
        match (d(a), d(b)) {
            (Some(u), Some(v)) => {
                if u.length_squared() <= v.length_squared() {
                    u
                } else {
                    -v
                }
            }
            (Some(u), None) => u,
            (None, Some(v)) => -v,
            (None, None) => Vec3::ZERO,
        }
    };
    let dx = pick((x + 1 < w).then(|| i + 1), (x > 0).then(|| i - 1));
    let dy = pick((y + 1 < h).then(|| i + w), (y > 0).then(|| i - w));
    (dx, dy)
}

/// Checks `distance` as the gather takes it.
fn check_distance(distance: f32) -> Result<()> {
    if distance >= 0.0 && distance.is_finite() {
        Ok(())
    } else {
        Err(VplaceError::OutOfRange {
            what: "distance".into(),
            value: distance.to_string(),
            expected: "finite and >= 0".into(),
        })
    }
}

/// Per pixel of `view`: the surface area it covers and its footprint (its shortest step to a
/// covered neighbour; infinite without one), 0 and infinite where not covered.
fn pixel_geometry(view: &View) -> (Vec<f32>, Vec<f32>) {
    let (w, h) = (view.width, view.height);
    let n = w * h;
    let mut area = vec![0.0f32; n];
    let mut footprint = vec![f32::INFINITY; n];
    area.par_iter_mut()
        .zip(footprint.par_iter_mut())
        .enumerate()
        .filter(|(i, _)| view.covered[*i])
        .for_each(|(i, (a, f))| {
            let (dx, dy) = steps(view, i % w, i / w);
            *a = dx.cross(dy).length();
            let (lx, ly) = (dx.length(), dy.length());
            *f = match (lx > 0.0, ly > 0.0) {
                (true, true) => lx.min(ly),
                (true, false) => lx,
                (false, true) => ly,
                (false, false) => f32::INFINITY,
            };
        });
    (area, footprint)
}

/// Per pixel, its unit normal where it gathers or gives near-field light (covered, and not
/// straddling two surfaces, whose averaged normal is short); `None` where it does neither.
fn whole_pixels(view: &View) -> Vec<Option<Vec3>> {
    (0..view.width * view.height)
        .into_par_iter()
        .map(|i| {
            let n = at(&view.normal, i);
            (view.covered[i] && n.length() > MIN_NORMAL).then(|| n.normalize_or_zero())
        })
        .collect()
}

/// One sample of a pixel's window that faces it within the distance: the sampled pixel `j`,
/// its unit normal, the offset `d` from the gathering point to it, `r^2`, the two cosines and
/// the number of pixels the sample stands for.
struct Sample {
    j: usize,
    ny: Vec3,
    d: Vec3,
    r2: f32,
    cx: f32,
    cy: f32,
    weight: f32,
}

/// Calls `visit` for every sample of pixel `i`'s window (a whole pixel, with `footprint` its
/// footprint) that lies within `distance` of it, faces it and is whole (`whole`, from
/// [`whole_pixels`], with the unit normals), as the gather takes them: every pixel of the
/// core, then every `k`-th pixel beyond it.
fn window(
    view: &View,
    whole: &[Option<Vec3>],
    i: usize,
    distance: f32,
    footprint: f32,
    mut visit: impl FnMut(Sample),
) {
    let (w, h) = (view.width, view.height);
    let (x, y) = ((i % w) as isize, (i / w) as isize);
    let Some(nx) = whole[i] else {
        return;
    };
    let p = at(&view.position, i);
    let d2max = distance * distance;
    // The window spans twice the distance at this pixel's footprint (a surface folding away
    // from the pixel, as across a corner, puts points within the distance further away on
    // screen), sampled every `k` pixels.
    let span = (2.0 * distance / footprint).ceil().min(4096.0) as usize;
    let k = span.div_ceil(GATHER_HALF_WINDOW).max(1);
    let half = (span / k).min(GATHER_HALF_WINDOW) as isize;
    let ki = k as isize;
    let mut sample = |dx: isize, dy: isize, weight: f32| {
        let (xx, yy) = (x + dx, y + dy);
        if (dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= w as isize || yy >= h as isize {
            return;
        }
        let j = yy as usize * w + xx as usize;
        let Some(ny) = whole[j] else {
            return;
        };
        let d = at(&view.position, j) - p;
        let r2 = d.length_squared();
        if r2 >= d2max || r2 <= 0.0 {
            return;
        }
        let om = d / r2.sqrt();
        let (cx, cy) = (nx.dot(om), -ny.dot(om));
        if cx <= 0.0 || cy <= 0.0 {
            return;
        }
        visit(Sample {
            j,
            ny,
            d,
            r2,
            cx,
            cy,
            weight,
        });
    };
    // Every pixel of the core, where the light of a corner comes from; beyond it, every `k`-th
    // pixel, each standing for `k x k`.
    let core = if k == 1 {
        half
    } else {
        DENSE_CORE.min(half * ki)
    };
    for oy in -core..=core {
        for ox in -core..=core {
            sample(ox, oy, 1.0);
        }
    }
    if k > 1 {
        let weight = (k * k) as f32;
        for oy in -half..=half {
            for ox in -half..=half {
                if (ox * ki).abs().max((oy * ki).abs()) > core {
                    sample(ox * ki, oy * ki, weight);
                }
            }
        }
    }
}

/// The near-field light of `view` (`H x W x 3` radiance, 0 where not covered) given the VPLs'
/// indirect image `vpl_indirect` of the same view, gathered within `distance` (world units; 0
/// gives zeros). With `scene`, a shadow ray between the two surfaces keeps each sample to what
/// the pixel sees; without, every sample counts. See the module docs.
///
/// # Errors
/// [`VplaceError::Shape`] when `vpl_indirect` is not the view's size;
/// [`VplaceError::OutOfRange`] for a negative or non-finite `distance`.
pub fn near_field_light(
    view: &View,
    vpl_indirect: &[f32],
    distance: f32,
    scene: Option<&Scene>,
) -> Result<Vec<f32>> {
    let (w, h) = (view.width, view.height);
    if vpl_indirect.len() != w * h * 3 {
        return Err(VplaceError::Shape {
            what: "vpl_indirect".into(),
            expected: format!("({h}, {w}, 3)"),
            got: format!("{} values", vpl_indirect.len()),
        });
    }
    check_distance(distance)?;
    let mut out = vec![0.0f32; w * h * 3];
    if distance == 0.0 {
        return Ok(out);
    }
    // Per pixel: its area on the surface, its footprint and its diffuse radiance.
    let (area, footprint) = pixel_geometry(view);
    let radiance: Vec<Vec3> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            if view.covered[i] {
                at(&view.albedo, i) * at(&view.diffuse_direct, i) + at(vpl_indirect, i)
            } else {
                Vec3::ZERO
            }
        })
        .collect();
    let eps = scene.map_or(0.0, Scene::ray_epsilon);
    let whole = whole_pixels(view);
    let state = || scene.map(Scene::shadow_state);
    out.par_chunks_mut(3)
        .enumerate()
        .for_each_init(state, |traversal, (i, px)| {
            // Pixels that straddle two surfaces average their normals: neither gather nor give.
            let Some(nx) = whole[i] else {
                return;
            };
            let p = at(&view.position, i);
            let mut e = Vec3::ZERO;
            // The projected solid angle the samples cover: at most pi, a whole hemisphere.
            let mut solid = 0.0f32;
            window(view, &whole, i, distance, footprint[i], |s| {
                if let (Some(scene), Some(t)) = (scene, traversal.as_mut()) {
                    let (from, to) = (p + nx * eps, p + s.d + s.ny * eps);
                    let seg = to - from;
                    let len = seg.length();
                    if len > 0.0
                        && scene.occluded_ray(
                            t,
                            &Ray::new(Vec3A::from(from), Vec3A::from(seg / len), 0.0, len),
                        )
                    {
                        return;
                    }
                }
                // The pixel as a disk of its area: `A / (r^2 + A / pi)` stays below pi where
                // `A / r^2` would not (two surfaces in contact).
                let a = area[s.j] * s.weight;
                let g = s.cx * s.cy * a / (s.r2 + a / std::f32::consts::PI);
                e += radiance[s.j] * g;
                solid += g;
            });
            if solid > std::f32::consts::PI {
                e *= std::f32::consts::PI / solid;
            }
            let add = at(&view.albedo, i) * e / std::f32::consts::PI;
            px.copy_from_slice(&add.to_array());
        });
    Ok(out)
}

/// Where [`near_field_light`] within `distance` can reach on `view`, from its geometry alone
/// (no shadow ray, no light): `(receivers, sources)`, each `H x W`. A pixel off `receivers`
/// gathers nothing whatever the light, and a receiver's gather reads the VPLs' light only at
/// `sources` pixels, so the gather of every pixel needs the VPLs' light only there. Both are
/// supersets: a shadow ray or a dark source may still leave a receiver with nothing.
///
/// # Errors
/// [`VplaceError::OutOfRange`] for a negative or non-finite `distance`.
pub fn near_field_reach(view: &View, distance: f32) -> Result<(Vec<bool>, Vec<bool>)> {
    check_distance(distance)?;
    let n = view.width * view.height;
    if distance == 0.0 {
        return Ok((vec![false; n], vec![false; n]));
    }
    let (area, footprint) = pixel_geometry(view);
    let whole = whole_pixels(view);
    let none = || (vec![false; n], vec![false; n]);
    let (receivers, sources) = (0..n)
        .into_par_iter()
        .filter(|&i| whole[i].is_some())
        .fold(none, |(mut receivers, mut sources), i| {
            window(view, &whole, i, distance, footprint[i], |s| {
                // A source of no area gives nothing.
                if area[s.j] > 0.0 {
                    receivers[i] = true;
                    sources[s.j] = true;
                }
            });
            (receivers, sources)
        })
        .reduce(none, |(mut r, mut s), (r2, s2)| {
            r.iter_mut().zip(r2).for_each(|(a, b)| *a |= b);
            s.iter_mut().zip(s2).for_each(|(a, b)| *a |= b);
            (r, s)
        });
    Ok((receivers, sources))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::{box_with, FloorView};
    use crate::view::{Camera, GBuffer, ViewInput};
    use std::f32::consts::PI;

    /// A concave corner seen head-on: the left half of a `w x h` image is the wall `x = 0`
    /// (normal `+X`, albedo `a`, unlit), the right half the floor `z = 0` (normal `+Z`,
    /// uniformly lit: diffuse radiance `l`), pixels of side `s` along both, the corner between
    /// them. Returns the view; pixel `(c, r)` of the wall lies `(w / 2 - c - 0.5) s` above the
    /// floor.
    fn corner(w: usize, h: usize, s: f32, a: f32, l: f32) -> View {
        let (mut position, mut normal, mut albedo, mut dd) = (vec![], vec![], vec![], vec![]);
        for r in 0..h {
            let y = (r as f32 + 0.5) * s;
            for c in 0..w {
                if c < w / 2 {
                    position.extend([0.0, y, (w / 2 - c) as f32 * s - 0.5 * s]);
                    normal.extend([1.0, 0.0, 0.0]);
                    albedo.extend([a; 3]);
                    dd.extend([0.0; 3]);
                } else {
                    position.extend([(c - w / 2) as f32 * s + 0.5 * s, y, 0.0]);
                    normal.extend([0.0, 0.0, 1.0]);
                    albedo.extend([0.5; 3]);
                    dd.extend([l / 0.5; 3]);
                }
            }
        }
        let covered = vec![true; w * h];
        let direct: Vec<f32> = dd.iter().zip(&albedo).map(|(d, a)| d * a).collect();
        let fv = FloorView::new(4, Vec3::Z, 1.0);
        View::new(&ViewInput {
            name: "corner",
            gbuffer: GBuffer {
                width: w,
                height: h,
                position: &position,
                normal: &normal,
                albedo: &albedo,
                covered: &covered,
            },
            depth: &vec![1.0; w * h],
            direct: &direct,
            diffuse_direct: &dd,
            diffuse_indirect: None,
            indirect: None,
            specular: None,
            diffuse_color: None,
            camera: Camera {
                position: fv.camera,
                world_to_clip: fv.world_to_clip,
            },
        })
        .expect("a valid view")
    }

    /// The irradiance at height `c` on the wall from the floor's points within `d` of it, per
    /// unit floor radiance: `int cos cos / r^2 dA` by a fine midpoint rule.
    fn reference(c: f32, d: f32) -> f32 {
        let n = 1200;
        let step = d / n as f32;
        let mut e = 0.0f64;
        for i in 0..n {
            let x = (i as f32 + 0.5) * step;
            for j in 0..2 * n {
                let y = (j as f32 + 0.5) * step - d;
                let r2 = x * x + y * y + c * c;
                if r2 < d * d {
                    // cos at the wall = x / r, cos at the floor = c / r.
                    e += f64::from(x * c / (r2 * r2) * step * step);
                }
            }
        }
        e as f32
    }

    #[test]
    fn a_corner_gathers_the_form_factor_of_the_lit_floor_within_the_distance() {
        // 0.01 m pixels, the distance 0.2 m: the window reaches 40 pixels, sampled every 3rd.
        let (w, h, s, a, l, d) = (80, 61, 0.01, 0.6, 2.0, 0.2);
        let view = corner(w, h, s, a, l);
        let none = vec![0.0; w * h * 3];
        let out = near_field_light(&view, &none, d, None).unwrap();
        let r = h / 2;
        for c in [w / 2 - 3, w / 2 - 6, w / 2 - 11, w / 2 - 16] {
            let height = (w / 2 - c) as f32 * s - 0.5 * s;
            let want = a / PI * l * reference(height, d);
            let got = out[3 * (r * w + c)];
            assert!(
                (got - want).abs() < 0.1 * want,
                "height {height}: gathered {got}, the integral {want}"
            );
        }
        // Beyond the distance nothing comes; the lit floor gets nothing from the dark wall;
        // close to the corner the wall sees nearly half its hemisphere filled.
        let far = w / 2 - 25;
        assert_eq!(out[3 * (r * w + far)], 0.0);
        assert_eq!(out[3 * (r * w + w / 2 + 3)], 0.0);
        let close = out[3 * (r * w + w / 2 - 1)];
        assert!(
            close > 0.3 * a * l && close < 0.5 * a * l,
            "at the corner: {close}"
        );
        // The VPLs' light is gathered like the captured light.
        let lit_floor: Vec<f32> = (0..w * h)
            .flat_map(|i| if i % w >= w / 2 { [l; 3] } else { [0.0; 3] })
            .collect();
        let dark = corner(w, h, s, a, 0.0);
        let via_vpls = near_field_light(&dark, &lit_floor, d, None).unwrap();
        for (x, y) in via_vpls.iter().zip(&out) {
            assert!((x - y).abs() <= 1e-5 * y.abs().max(1.0));
        }
    }

    #[test]
    fn a_card_between_the_wall_and_the_floor_blocks_the_gather() {
        let (w, h, s, a, l, d) = (80, 61, 0.01, 0.6, 2.0, 0.2);
        let view = corner(w, h, s, a, l);
        let none = vec![0.0; w * h * 3];
        let open = near_field_light(&view, &none, d, None).unwrap();
        // The corner inside the test box (floor z = 0, walls at +-1): nothing in the way.
        let boxed = box_with(vec![], &[]);
        let seen = near_field_light(&view, &none, d, Some(&boxed)).unwrap();
        // A card standing 5 cm in front of the wall, 2 mm above the floor.
        let card = [
            Vec3::new(0.05, -1.0, 0.002),
            Vec3::new(0.05, 1.0, 0.002),
            Vec3::new(0.05, 1.0, 1.0),
            Vec3::new(0.05, -1.0, 1.0),
        ];
        let carded = box_with(vec![], &[card]);
        let blocked = near_field_light(&view, &none, d, Some(&carded)).unwrap();
        let i = 3 * ((h / 2) * w + w / 2 - 11); // 0.105 m up the wall
        assert!(open[i] > 0.0);
        assert!(
            (seen[i] - open[i]).abs() < 1e-3 * open[i],
            "{} {}",
            seen[i],
            open[i]
        );
        assert!(blocked[i] < 0.5 * open[i], "{} {}", blocked[i], open[i]);
    }

    #[test]
    fn surfaces_in_contact_gather_no_more_than_a_lit_hemisphere() {
        // Pixels of 10 micrometres, gathered within a metre: the sum of `A / r^2` over the
        // floor's pixels next to the corner would pass pi many times over.
        let (w, h, a, l) = (40, 21, 0.8, 3.0);
        let view = corner(w, h, 1e-5, a, l);
        let out = near_field_light(&view, &vec![0.0; w * h * 3], 1.0, None).unwrap();
        assert!(out.iter().all(|&v| v.is_finite() && v <= a * l * 1.0001));
        let r = h / 2;
        assert!(out[3 * (r * w + w / 2 - 1)] > 0.3 * a * l);
    }

    #[test]
    fn a_flat_floor_gathers_nothing_and_zero_distance_gives_zeros() {
        let fv = FloorView::new(16, Vec3::new(0.0, 0.0, 1.0), 50.0);
        let view = fv.view();
        let ind = vec![0.3; 16 * 16 * 3];
        assert!(near_field_light(&view, &ind, 1.0, None)
            .unwrap()
            .iter()
            .all(|&v| v == 0.0));
        let corner = corner(8, 4, 0.1, 0.5, 1.0);
        let ind = vec![0.0; 8 * 4 * 3];
        assert!(near_field_light(&corner, &ind, 0.0, None)
            .unwrap()
            .iter()
            .all(|&v| v == 0.0));
    }

    #[test]
    fn bad_input_is_an_error() {
        let view = corner(8, 4, 0.1, 0.5, 1.0);
        assert!(matches!(
            near_field_light(&view, &[0.0; 5], 0.1, None),
            Err(VplaceError::Shape { .. })
        ));
        for d in [-0.1, f32::NAN, f32::INFINITY] {
            assert!(matches!(
                near_field_light(&view, &[0.0; 96], d, None),
                Err(VplaceError::OutOfRange { .. })
            ));
        }
    }

    #[test]
    fn the_reach_holds_every_pixel_the_gather_reads_and_lights() {
        // The corner, lit by the VPLs as well (a pattern, so that a wrong source would show).
        let (w, h, s, a, l, d) = (80, 61, 0.01, 0.6, 2.0, 0.2);
        let view = corner(w, h, s, a, l);
        let vpl: Vec<f32> = (0..w * h * 3).map(|i| (i % 7) as f32 * 0.1).collect();
        let full = near_field_light(&view, &vpl, d, None).unwrap();
        let (receivers, sources) = near_field_reach(&view, d).unwrap();
        // Gathering points near the corner, beyond it none.
        let r = h / 2;
        assert!(receivers[r * w + w / 2 - 3] && !receivers[r * w + w / 2 - 25]);
        assert!(sources[r * w + w / 2 + 3] && !sources[r * w + w / 2 + 25]);
        for (i, &on) in receivers.iter().enumerate() {
            if !on {
                assert_eq!(&full[3 * i..3 * i + 3], &[0.0; 3], "pixel {i} gathers");
            }
        }
        // The VPLs' light off the sources changes no pixel's gather.
        let kept: Vec<f32> = (0..w * h * 3)
            .map(|i| if sources[i / 3] { vpl[i] } else { 0.0 })
            .collect();
        assert_eq!(near_field_light(&view, &kept, d, None).unwrap(), full);
        let (none, _) = near_field_reach(&view, 0.0).unwrap();
        assert!(none.iter().all(|&r| !r));
        assert!(near_field_reach(&view, f32::NAN).is_err());
        // A flat floor gathers nowhere.
        let flat = FloorView::new(16, Vec3::new(0.0, 0.0, 1.0), 50.0).view();
        let (r, s) = near_field_reach(&flat, 1.0).unwrap();
        assert!(r.iter().chain(&s).all(|&x| !x));
    }

    #[test]
    fn the_distance_follows_the_median_radius() {
        let f = GATHER_RADIUS_FACTOR;
        assert_eq!(gather_distance(&[]), 0.0);
        assert_eq!(gather_distance(&[0.3, 0.1, 0.2]), f * 0.2);
        assert_eq!(gather_distance(&[0.4, 0.1, f32::NAN, 0.2, 0.3]), f * 0.3);
    }
}
