//! The scene's working scale: the size of the region the cameras work in, which VPL sizes and
//! ray offsets follow ([`Scene::scale`], [`Scene::with_eyes`]).
//!
//! A scene's bounds hold geometry no camera sees: a ground plane of a kilometre under a room, a
//! backdrop, a second building. A VPL's near-field disk, its offset off its surface and the ray
//! offsets are fractions of the scene's size; taken from the bounds, a 1 km plane under a room of
//! 8 m made every VPL a disk of 14 m lifted 1.4 m off its surface. So the scale is the diagonal
//! of what rays from the cameras' eyes meet, in every direction (the region a camera in that
//! place may see, not only the one view): per axis, the [`REGION_QUANTILE`] and
//! `1 - REGION_QUANTILE` quantiles of the hit points and the eyes, so that a few rays that leave
//! through a window and meet the far ground do not stretch it, leaving out each eye's hits beyond
//! [`BACKDROP_FACTOR`] times their median distance (or the median of those it looks at, where
//! less), so that more of them do not either (a sky
//! dome of 2 km round a room open on one side made every VPL a disk of 69 m, lifted 6.9 m off its
//! surface and out of the room). The scale is the bounds'
//! diagonal, or [`REGION_MARGIN`] times the region's where that is less: it changes only where
//! most of the bounds lie beyond the region (a room's inner surfaces are a few per cent less
//! than its bounds with the walls' thickness; a camera in one room of a flat sees part of it),
//! and every built-in scene keeps its bounds.

use glam::Vec3;
use rayon::prelude::*;

use crate::error::{check_finite, Result};
use crate::scene::Scene;

/// Rays traced from each eye, spread evenly over the sphere (a Fibonacci lattice).
pub const REGION_RAYS: usize = 4096;
/// The share of the hit points left out at each end of each axis.
pub const REGION_QUANTILE: f32 = 0.01;
/// An eye's hits beyond this many times the [`BACKDROP_QUANTILE`] of its hit distances are a
/// backdrop (a sky dome of kilometres round a room open on one side, which a fifth of the rays
/// met), not the region.
pub const BACKDROP_FACTOR: f32 = 20.0;
/// The share of an eye's hits that stand for how far it sees all round ([`BACKDROP_FACTOR`]):
/// the median. (A quarter cut Sponza's far end from its main camera, which stands by a pillar:
/// its scale 63.6 -> 42.3 m. Where more than half the rays leave for a dome, what the camera
/// looks at says how far it sees: [`region_box_looking`].)
pub const BACKDROP_QUANTILE: f32 = 0.5;
/// The cosine of the cone about a camera's view direction whose hits say how far it looks
/// ([`region_box_looking`]): 30 degrees.
pub const VIEW_CONE_COS: f32 = 0.866;
/// The scale is at most this many times the region's diagonal (and at most the bounds'). With 2
/// the built-in scenes keep their bounds (their fit cameras' regions: 0.68-1.0 of them).
pub const REGION_MARGIN: f32 = 2.0;

/// `n` unit directions spread evenly over the sphere (a Fibonacci lattice).
#[must_use]
pub fn sphere_directions(n: usize) -> Vec<Vec3> {
    let golden_angle = std::f64::consts::PI * (3.0 - 5.0f64.sqrt());
    (0..n)
        .map(|i| {
            let i = i as f64 + 0.5;
            let z = 1.0 - 2.0 * i / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = i * golden_angle;
            Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32)
        })
        .collect()
}

/// The box of the region seen from `eyes` (see the module docs), `(min, max)`, or `None` when
/// no ray from them meets a surface. Each eye's hits further than [`BACKDROP_FACTOR`] times
/// the [`BACKDROP_QUANTILE`] of its hit distances are left out: a backdrop, not the place the
/// camera works in.
#[must_use]
pub fn region_box(scene: &Scene, eyes: &[Vec3]) -> Option<(Vec3, Vec3)> {
    region_box_looking(scene, eyes, &[])
}

/// [`region_box`] with each eye's view direction (`looks[i]`, unit; zero, or `looks` empty,
/// for none): where what it looks at lies nearer than its hits all round do (a camera outside
/// a room open towards it, in a dome), the median distance of the hits within
/// [`VIEW_CONE_COS`] of the direction sets its backdrop instead.
#[must_use]
pub fn region_box_looking(scene: &Scene, eyes: &[Vec3], looks: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let dirs = sphere_directions(REGION_RAYS);
    let mut points: Vec<Vec3> = eyes
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, &eye)| {
            let hits: Vec<(Vec3, f32, Vec3)> = dirs
                .iter()
                .filter_map(|&d| {
                    scene
                        .closest_hit(eye, d, 0.0, f32::INFINITY)
                        .map(|h| (eye + d * h.t, h.t, d))
                })
                .collect();
            let far = BACKDROP_FACTOR * near_distance(&hits, looks.get(i).copied());
            hits.into_iter().filter(move |h| h.1 <= far).map(|h| h.0)
        })
        .collect();
    if points.is_empty() {
        return None;
    }
    points.extend_from_slice(eyes);
    Some(quantile_box(&points))
}

/// How far an eye sees, from its hits `(point, distance, direction)`: the
/// [`BACKDROP_QUANTILE`] of their distances, or with a view direction `look` the median of
/// those within [`VIEW_CONE_COS`] of it where that is less; infinite without hits.
fn near_distance(hits: &[(Vec3, f32, Vec3)], look: Option<Vec3>) -> f32 {
    let quantile = |mut t: Vec<f32>, q: f32| {
        t.sort_unstable_by(f32::total_cmp);
        t.get((q * t.len() as f32) as usize)
            .copied()
            .unwrap_or(f32::INFINITY)
    };
    let all = quantile(hits.iter().map(|h| h.1).collect(), BACKDROP_QUANTILE);
    let viewed = match look {
        Some(l) if l != Vec3::ZERO => quantile(
            hits.iter()
                .filter(|h| h.2.dot(l) >= VIEW_CONE_COS)
                .map(|h| h.1)
                .collect(),
            0.5,
        ),
        _ => f32::INFINITY,
    };
    all.min(viewed)
}

/// The diagonal of [`region_box`].
#[must_use]
pub fn region_diagonal(scene: &Scene, eyes: &[Vec3]) -> Option<f32> {
    region_box(scene, eyes).map(|(lo, hi)| (hi - lo).length())
}

/// Per axis, the [`REGION_QUANTILE`] and `1 - REGION_QUANTILE` quantiles of `points` (not
/// empty).
fn quantile_box(points: &[Vec3]) -> (Vec3, Vec3) {
    let mut lo = Vec3::ZERO;
    let mut hi = Vec3::ZERO;
    let mut axis: Vec<f32> = Vec::with_capacity(points.len());
    for k in 0..3 {
        axis.clear();
        axis.extend(points.iter().map(|p| p[k]));
        axis.sort_unstable_by(f32::total_cmp);
        let last = axis.len() - 1;
        let cut = (REGION_QUANTILE * last as f32).round() as usize;
        lo[k] = axis[cut];
        hi[k] = axis[last - cut];
    }
    (lo, hi)
}

impl Scene {
    /// The scene with its working scale ([`Scene::scale`]) taken from the region seen from
    /// `eyes`, the cameras' positions (see the module docs): at most [`REGION_MARGIN`] times
    /// that region's diagonal and at most the bounds' diagonal; where it is less, the sun and
    /// the world send their light through the region ([`Scene::emission_sphere`]). No eyes, or
    /// eyes from which no ray meets a surface, keep the bounds' diagonal and sphere.
    ///
    /// Errors: a non-finite eye.
    pub fn with_eyes(self, eyes: &[Vec3]) -> Result<Self> {
        self.with_views(eyes, &[])
    }

    /// [`Scene::with_eyes`] with each eye's view direction, `looks[i]` (unit, or zero for
    /// none, as for a panoramic camera; or `looks` empty): see [`region_box_looking`].
    ///
    /// Errors: a non-finite eye or look, or `looks` neither empty nor one per eye.
    pub fn with_views(mut self, eyes: &[Vec3], looks: &[Vec3]) -> Result<Self> {
        for eye in eyes {
            check_finite("eyes", &eye.to_array())?;
        }
        for look in looks {
            check_finite("looks", &look.to_array())?;
        }
        if !looks.is_empty() && looks.len() != eyes.len() {
            return Err(crate::error::VplaceError::Shape {
                what: "looks".into(),
                expected: format!("({}, 3), one per eye", eyes.len()),
                got: format!("({}, 3)", looks.len()),
            });
        }
        let looks: Vec<Vec3> = looks.iter().map(|l| l.normalize_or_zero()).collect();
        if let Some((lo, hi)) = region_box_looking(&self, eyes, &looks) {
            let scale = (REGION_MARGIN * (hi - lo).length()).clamp(1e-6, self.diagonal());
            if scale < self.diagonal() {
                self.scale = scale;
                self.region = Some((lo, hi));
            }
        }
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::emitters::light_power;
    use crate::scene::Light;
    use crate::test_util::{box_with, closed_box};
    use crate::vpl::uniform_vpls;

    /// The box of `test_util::closed_box` (`[-1, 1]^2 x [0, 2]`) over a square of `size`
    /// metres 1 m below it, with `lights`.
    fn lit_room_on_ground(size: f32, lights: Vec<Light>) -> Scene {
        let h = 0.5 * size;
        let p = |x: f32, y: f32| Vec3::new(x, y, -1.0);
        box_with(lights, &[[p(-h, -h), p(h, -h), p(h, h), p(-h, h)]])
    }

    fn room_on_ground(size: f32) -> Scene {
        lit_room_on_ground(size, vec![])
    }

    /// The share of `n` first-bounce VPLs inside the box.
    fn inside_share(scene: &Scene, n: usize) -> f32 {
        let vpls = uniform_vpls(scene, n, 7).unwrap();
        let inside = vpls
            .iter()
            .filter(|v| v.position.x.abs() < 1.0 && v.position.y.abs() < 1.0)
            .filter(|v| v.position.z > 0.0 && v.position.z < 2.0)
            .count();
        inside as f32 / vpls.len() as f32
    }

    #[test]
    fn the_world_lights_the_region_not_a_ground_no_camera_sees() {
        // a lamp in the closed box and a world that lights its outside and the ground: the VPLs
        // inside the box are the ones the camera in it sees
        let lights = || {
            vec![
                Light::point(Vec3::new(0.0, 0.0, 1.5), Vec3::splat(100.0)),
                Light::world(Vec3::splat(0.5), None),
            ]
        };
        let eye = [Vec3::new(0.3, -0.2, 1.2)];
        let room = closed_box(lights()).with_eyes(&eye).unwrap();
        let ground = lit_room_on_ground(1000.0, lights());
        let (alone, lost) = (inside_share(&room, 2000), inside_share(&ground, 2000));
        let ground = ground.with_eyes(&eye).unwrap();
        let kept = inside_share(&ground, 2000);
        assert!(lost < 0.01, "{lost}");
        // the lamp's VPLs are inside, the world's (through the region's sphere) outside
        let power = |l: &Light| crate::color::luminance(light_power(l, &ground));
        let expect =
            power(&ground.lights[0]) / (power(&ground.lights[0]) + power(&ground.lights[1]));
        assert!((kept - expect).abs() < 0.05, "{kept} {expect}");
        assert!(kept < alone, "{kept} {alone}");
        let (centre, radius, start) = ground.emission_sphere();
        assert!(
            (centre - Vec3::new(0.0, 0.0, 1.0)).length() < 0.1,
            "{centre}"
        );
        assert_eq!(radius, 0.5 * ground.scale());
        // the rays start outside every triangle: beyond the ground's far corner
        assert!(start > 2.0 * 500.0 * 2f32.sqrt(), "{start}");
        // without eyes: the bounding sphere
        let (c, r) = room.bounding_sphere();
        assert_eq!(room.emission_sphere(), (c, r, 2.0 * r));
    }

    #[test]
    fn directions_are_unit_and_balanced() {
        let d = sphere_directions(REGION_RAYS);
        assert!(d.iter().all(|v| (v.length() - 1.0).abs() < 1e-5));
        let mean = d.iter().copied().sum::<Vec3>() / d.len() as f32;
        assert!(mean.length() < 1e-3, "{mean}");
    }

    #[test]
    fn a_ground_no_camera_sees_leaves_the_scale_of_the_room() {
        let room = closed_box(vec![]);
        let eye = Vec3::new(0.3, -0.2, 1.2);
        let ground = room_on_ground(1000.0);
        assert!(ground.diagonal() > 1000.0);
        // without eyes: the bounds
        assert_eq!(ground.scale(), ground.diagonal());
        assert_eq!(ground.region(), None);
        let region = region_diagonal(&room, &[eye]).unwrap();
        assert!((region - room.diagonal()).abs() < 1e-3 * region, "{region}");
        let room = room.with_eyes(&[eye]).unwrap();
        let ground = ground.with_eyes(&[eye]).unwrap();
        // the closed room's region is its bounds: kept; the ground's scale is the room's region
        assert_eq!(room.scale(), room.diagonal());
        assert_eq!(room.region(), None);
        assert_eq!(ground.scale(), REGION_MARGIN * region);
        let (lo, hi) = ground.region().unwrap();
        assert!(lo.abs_diff_eq(Vec3::new(-1.0, -1.0, 0.0), 1e-3), "{lo}");
        assert!(hi.abs_diff_eq(Vec3::new(1.0, 1.0, 2.0), 1e-3), "{hi}");
        let (r, e) = (room.near_field_radius(), room.ray_epsilon());
        assert!((ground.near_field_radius() - REGION_MARGIN * r).abs() < 1e-5 * r);
        assert!((ground.ray_epsilon() - REGION_MARGIN * e).abs() < 1e-5 * e);
    }

    #[test]
    fn an_eye_that_sees_nothing_keeps_the_bounds_and_bad_eyes_are_refused() {
        let scene = room_on_ground(10.0);
        let d = scene.diagonal();
        let far = Vec3::new(0.0, 0.0, 1e6);
        // from far above, the ground fills too little of the sphere for any ray to meet it
        let scene = scene.with_eyes(&[far]).unwrap();
        assert_eq!(scene.scale(), d);
        assert!(scene.with_eyes(&[Vec3::new(f32::NAN, 0.0, 0.0)]).is_err());
    }

    #[test]
    fn an_eye_on_open_ground_gets_a_region_far_below_the_ground() {
        // a camera 1.7 m over a plane of 10 km: rays meet it out to the horizon, but the
        // quantiles keep the region to what is near (302 m of the bounds' 14 km)
        let scene = room_on_ground(10_000.0);
        let eye = Vec3::new(100.0, 100.0, 0.7);
        let scene = scene.with_eyes(&[eye]).unwrap();
        assert!(scene.scale() < 0.03 * scene.diagonal(), "{}", scene.scale());
        assert!(scene.scale() > 10.0, "{}", scene.scale());
    }

    /// A room `[-1, 1]^2 x [0, 2]` open on its `-y` side, inside a cube of half size `dome`
    /// round the origin (a sky dome modelled as a mesh).
    fn open_room_in_dome(dome: f32) -> Scene {
        let p = Vec3::new;
        let mut quads = vec![
            [
                p(-1., -1., 0.),
                p(1., -1., 0.),
                p(1., 1., 0.),
                p(-1., 1., 0.),
            ],
            [
                p(-1., -1., 2.),
                p(-1., 1., 2.),
                p(1., 1., 2.),
                p(1., -1., 2.),
            ],
            [p(-1., 1., 0.), p(1., 1., 0.), p(1., 1., 2.), p(-1., 1., 2.)],
            [
                p(-1., -1., 0.),
                p(-1., 1., 0.),
                p(-1., 1., 2.),
                p(-1., -1., 2.),
            ],
            [p(1., -1., 0.), p(1., -1., 2.), p(1., 1., 2.), p(1., 1., 0.)],
        ];
        let d = dome;
        quads.extend([
            [p(-d, -d, -d), p(-d, d, -d), p(d, d, -d), p(d, -d, -d)],
            [p(-d, -d, d), p(d, -d, d), p(d, d, d), p(-d, d, d)],
            [p(-d, -d, -d), p(d, -d, -d), p(d, -d, d), p(-d, -d, d)],
            [p(-d, d, -d), p(-d, d, d), p(d, d, d), p(d, d, -d)],
            [p(-d, -d, -d), p(-d, -d, d), p(-d, d, d), p(-d, d, -d)],
            [p(d, -d, -d), p(d, d, -d), p(d, d, d), p(d, -d, d)],
        ]);
        let mut v = Vec::new();
        let mut t = Vec::new();
        for q in quads {
            let base = v.len() as u32;
            v.extend(q);
            t.push([base, base + 1, base + 2]);
            t.push([base, base + 2, base + 3]);
        }
        let ids = vec![0; t.len()];
        Scene::build(&v, &t, &ids, &[Vec3::splat(0.5)], vec![]).unwrap()
    }

    #[test]
    fn a_sky_dome_round_a_room_open_on_one_side_is_a_backdrop() {
        // (the eye's median distance all round: no view direction needed)
        // a fifth of the rays leave the room through its open side and meet the dome 2 km away:
        // the region is the room (and the eye), not the dome
        let eye = Vec3::new(0.0, -0.5, 1.0);
        let scene = open_room_in_dome(2000.0);
        assert!(scene.diagonal() > 6000.0);
        let scene = scene.with_eyes(&[eye]).unwrap();
        // (its open side holds only the edges of the floor, ceiling and walls: the quantile
        // stops short of it)
        let (lo, hi) = scene.region().unwrap();
        assert!(lo.abs_diff_eq(Vec3::new(-1.0, -1.0, 0.0), 0.05), "{lo}");
        assert!(hi.abs_diff_eq(Vec3::new(1.0, 1.0, 2.0), 1e-3), "{hi}");
        assert!(scene.scale() < 10.0, "{}", scene.scale());
        // a dome within the backdrop factor of the eye's near distances stays in the region
        let near = open_room_in_dome(3.0).with_eyes(&[eye]).unwrap();
        assert_eq!(near.region(), None);
        assert_eq!(near.scale(), near.diagonal());
    }

    #[test]
    fn a_camera_outside_the_room_looking_in_takes_the_room_not_the_dome() {
        // from 1.5 m outside the open side, fewer than a quarter of the rays meet the room; the
        // camera looks into it, and the hits it looks at set its backdrop
        let eye = Vec3::new(0.0, -2.5, 1.0);
        let dome = || open_room_in_dome(2000.0);
        let all_round = dome().with_eyes(&[eye]).unwrap();
        assert_eq!(all_round.scale(), all_round.diagonal());
        let looking = dome().with_views(&[eye], &[Vec3::Y]).unwrap();
        assert!(looking.scale() < 12.0, "{}", looking.scale());
        let (lo, hi) = looking.region().unwrap();
        assert!(lo.cmpge(Vec3::new(-1.01, -2.51, -0.01)).all(), "{lo}");
        assert!(hi.cmple(Vec3::new(1.01, 1.01, 2.01)).all(), "{hi}");
        // looking away from the room (or no direction) keeps the rule all round
        let away = dome().with_views(&[eye], &[Vec3::NEG_Y]).unwrap();
        assert_eq!(away.scale(), away.diagonal());
        let none = dome().with_views(&[eye], &[Vec3::ZERO]).unwrap();
        assert_eq!(none.scale(), none.diagonal());
        assert!(dome().with_views(&[eye], &[Vec3::Y, Vec3::Y]).is_err());
        assert!(dome().with_views(&[eye], &[Vec3::splat(f32::NAN)]).is_err());
    }
}
