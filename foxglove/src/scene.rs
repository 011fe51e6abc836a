//! The robot in Foxglove's 3D panel: frames and primitives built from the model's geometry.
//!
//! Axes: Foxglove's 3D world is `z` up, so the model's plane (`docs/model.md`: origin at the
//! plate's left edge lying flat, `x` to the right, `y` up, m) is its `x`-`z` plane: a model
//! point `(x, y)` is `(x, 0, y)`, and a counter-clockwise model angle is a rotation about
//! `-y`. Frames ([`transforms`]):
//!
//! - `plate`, child of `world`: origin at the plate's centre on its contact line (where the arm
//!   is mounted), `x` along the plate towards its right edge; rotated by the tilt `alpha`;
//! - `arm`, child of `plate`: same origin, `x` along the arm towards its tip (at `x = l`);
//!   rotated by `beta` relative to the plate.
//!
//! So the plate's left and right edges are `(-f, 0, 0)` and `(f, 0, 0)` in `plate`, and the tip
//! is `(l, 0, 0)` in `arm`. The primitives ([`entities`]) are frame-locked to these frames: a
//! slab for the plate, a cylinder and a ball for the arm (each named by a small label), an orange line along the active pivot
//! edge, a ground slab, a title stating the tilt exaggeration, and a red ball flashed at the
//! edge that strikes the ground at a landing ([`landing_flash`]).
//!
//! With a tilt exaggeration `k` (display only), the plate is drawn at `k alpha` about the same
//! pivot; `k = 1` (the default) is the model's kinematics exactly.

use foxglove::messages::{
    Color, CubePrimitive, CylinderPrimitive, Duration, FrameTransform, FrameTransforms,
    LinePrimitive, Point3, Pose, Quaternion, SceneEntity, SpherePrimitive, TextPrimitive,
    Timestamp, Vector3,
};
use tilting_plant::kinematics::{pivot, point_masses};
use tilting_plant::{Mode, Params, State};

/// The root frame.
pub const WORLD: &str = "world";
/// The plate's frame.
pub const PLATE: &str = "plate";
/// The arm's frame.
pub const ARM: &str = "arm";

/// How long a landing is flashed (s of plant time).
pub const FLASH: f64 = 0.15;

/// Largest tilt exaggeration.
pub const MAX_EXAGGERATION: f64 = 100.0;

/// Checks a tilt exaggeration: a factor from 1 to [`MAX_EXAGGERATION`].
pub fn check_exaggeration(k: f64) -> Result<f64, String> {
    if k.is_finite() && (1.0..=MAX_EXAGGERATION).contains(&k) {
        Ok(k)
    } else {
        Err(format!(
            "invalid `--tilt-exaggeration` = {k}: allowed 1 (to scale) to {MAX_EXAGGERATION}"
        ))
    }
}

/// The title shown above the robot: the robot's name and the tilt's scale.
pub fn title(robot: &str, k: f64) -> String {
    if k == 1.0 {
        format!("tilting/{robot}: tilt to scale")
    } else {
        format!("tilting/{robot}: tilt exaggerated x{k} (display only)")
    }
}

/// A plant time (s) as a Foxglove timestamp (negative times clamp to 0).
pub fn timestamp(t: f64) -> Timestamp {
    let ns = nanos(t);
    Timestamp::new((ns / 1_000_000_000) as u32, (ns % 1_000_000_000) as u32)
}

/// A plant time (s) in ns (negative times clamp to 0).
pub fn nanos(t: f64) -> u64 {
    (t.max(0.0) * 1e9).round() as u64
}

/// A model point `(x, y)` (m) in Foxglove's world.
fn point(x: f64, y: f64) -> Vector3 {
    Vector3 { x, y: 0.0, z: y }
}

/// The rotation by a counter-clockwise model angle `a` (rad): about `-y`.
pub fn rotation(a: f64) -> Quaternion {
    let (s, c) = (0.5 * a).sin_cos();
    Quaternion {
        x: 0.0,
        y: -s,
        z: 0.0,
        w: c,
    }
}

/// The frames `plate` and `arm` at plant time `t` for `mode`, tilt `alpha` and arm angle
/// `beta` (rad), with the plate drawn at `k alpha`.
pub fn transforms(
    p: &Params,
    k: f64,
    t: f64,
    mode: Mode,
    alpha: f64,
    beta: f64,
) -> FrameTransforms {
    let a = k * alpha;
    let centre = point_masses(p, mode, &State::new(a, beta, 0.0, 0.0)).foot;
    let ts = Some(timestamp(t));
    FrameTransforms {
        transforms: vec![
            FrameTransform {
                timestamp: ts,
                parent_frame_id: WORLD.into(),
                child_frame_id: PLATE.into(),
                translation: Some(point(centre.x, centre.y)),
                rotation: Some(rotation(a)),
            },
            FrameTransform {
                timestamp: ts,
                parent_frame_id: PLATE.into(),
                child_frame_id: ARM.into(),
                translation: Some(point(0.0, 0.0)),
                rotation: Some(rotation(beta)),
            },
        ],
    }
}

fn rgba(r: f64, g: f64, b: f64, a: f64) -> Option<Color> {
    Some(Color { r, g, b, a })
}

fn pose_at(x: f64, y: f64, z: f64, orientation: Quaternion) -> Option<Pose> {
    Some(Pose {
        position: Some(Vector3 { x, y, z }),
        orientation: Some(orientation),
    })
}

const IDENTITY: Quaternion = Quaternion {
    x: 0.0,
    y: 0.0,
    z: 0.0,
    w: 1.0,
};

fn entity(t: f64, frame: &str, id: &str) -> SceneEntity {
    SceneEntity {
        timestamp: Some(timestamp(t)),
        frame_id: frame.into(),
        id: id.into(),
        frame_locked: true,
        ..SceneEntity::default()
    }
}

/// The robot's entities at plant time `t` in `mode`: ground, plate (red while `flashing`),
/// the active pivot edge (none when flat), the arm and the title.
pub fn entities(p: &Params, title: &str, t: f64, mode: Mode, flashing: bool) -> Vec<SceneEntity> {
    let (f, l) = (p.f, p.l);
    let depth = f;
    let thick = 0.06 * f;
    let mut ground = entity(t, WORLD, "ground");
    ground.cubes.push(CubePrimitive {
        pose: pose_at(f, 0.0, -0.5 * thick, IDENTITY),
        size: Some(Vector3 {
            x: 4.0 * f + 2.0 * l,
            y: 2.0 * depth,
            z: thick,
        }),
        color: rgba(0.55, 0.55, 0.5, 1.0),
    });
    let mut plate = entity(t, PLATE, "plate");
    plate.cubes.push(CubePrimitive {
        pose: pose_at(0.0, 0.0, 0.5 * thick, IDENTITY),
        size: Some(Vector3 {
            x: 2.0 * f,
            y: depth,
            z: thick,
        }),
        color: if flashing {
            rgba(0.9, 0.1, 0.1, 1.0)
        } else {
            rgba(0.2, 0.35, 0.7, 1.0)
        },
    });
    plate.texts.push(label(f, 0.0, 3.0 * thick, "plate"));
    let mut edge = entity(t, PLATE, "pivot");
    if mode.is_tilted() {
        let x = if mode == Mode::Right { f } else { -f };
        edge.lines.push(LinePrimitive {
            r#type: 0,
            pose: pose_at(0.0, 0.0, 0.0, IDENTITY),
            thickness: 6.0,
            scale_invariant: true,
            points: vec![
                Point3 {
                    x,
                    y: -0.6 * depth,
                    z: 0.0,
                },
                Point3 {
                    x,
                    y: 0.6 * depth,
                    z: 0.0,
                },
            ],
            color: rgba(1.0, 0.55, 0.0, 1.0),
            ..LinePrimitive::default()
        });
    }
    let mut arm = entity(t, ARM, "arm");
    let r = 0.03 * l;
    // The cylinder's axis is its z: turned onto the arm's x by +90 degrees about y.
    let (s, c) = std::f64::consts::FRAC_PI_4.sin_cos();
    arm.cylinders.push(CylinderPrimitive {
        pose: pose_at(
            0.5 * l,
            0.0,
            0.0,
            Quaternion {
                x: 0.0,
                y: s,
                z: 0.0,
                w: c,
            },
        ),
        size: Some(Vector3 { x: r, y: r, z: l }),
        bottom_scale: 1.0,
        top_scale: 1.0,
        color: rgba(0.15, 0.15, 0.15, 1.0),
    });
    arm.spheres.push(SpherePrimitive {
        pose: pose_at(l, 0.0, 0.0, IDENTITY),
        size: Some(Vector3 {
            x: 4.0 * r,
            y: 4.0 * r,
            z: 4.0 * r,
        }),
        color: rgba(0.85, 0.45, 0.1, 1.0),
    });
    arm.texts.push(label(0.6 * l, 0.0, 4.0 * r, "arm"));
    let mut text = entity(t, WORLD, "title");
    text.texts.push(TextPrimitive {
        pose: pose_at(f, 0.0, 1.25 * l, IDENTITY),
        billboard: true,
        font_size: 16.0,
        scale_invariant: true,
        color: rgba(0.1, 0.1, 0.1, 1.0),
        text: format!("{title}\nmode {mode}, t = {t:.2} s"),
    });
    vec![ground, plate, edge, arm, text]
}

/// A small name written beside a part, at `(x, y, z)` in its frame.
fn label(x: f64, y: f64, z: f64, text: &str) -> TextPrimitive {
    TextPrimitive {
        pose: pose_at(x, y, z, IDENTITY),
        billboard: true,
        font_size: 12.0,
        scale_invariant: true,
        color: rgba(0.25, 0.25, 0.25, 1.0),
        text: text.into(),
    }
}

/// The landing flash at plant time `t`: a red ball for [`FLASH`] s at the edge that strikes the
/// ground, the one opposite the pivot the plate was tilted about (`from`).
pub fn landing_flash(p: &Params, t: f64, from: Mode) -> SceneEntity {
    let strike = pivot(p, from.mirrored());
    let mut e = entity(t, WORLD, "landing");
    e.frame_locked = false;
    e.lifetime = Some(Duration::new(0, (FLASH * 1e9) as u32));
    let d = 0.5 * p.f;
    e.spheres.push(SpherePrimitive {
        pose: pose_at(strike.x, 0.0, strike.y, IDENTITY),
        size: Some(Vector3 { x: d, y: d, z: d }),
        color: rgba(0.95, 0.05, 0.05, 0.8),
    });
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rotates `v` by the unit quaternion `q` (`q v q*`).
    fn rotate(q: &Quaternion, v: [f64; 3]) -> [f64; 3] {
        let u = [q.x, q.y, q.z];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let t = cross(u, v).map(|c| 2.0 * c);
        let ut = cross(u, t);
        [0, 1, 2].map(|i| v[i] + q.w * t[i] + ut[i])
    }

    fn apply(tf: &FrameTransform, v: [f64; 3]) -> [f64; 3] {
        let r = rotate(tf.rotation.as_ref().unwrap(), v);
        let o = tf.translation.unwrap();
        [r[0] + o.x, r[1] + o.y, r[2] + o.z]
    }

    /// The plate's edges and the arm's tip through the two transforms equal the model's
    /// kinematics (`point_masses`, independent of the quaternions) in every mode, to 1e-12 m.
    #[test]
    fn frames_reproduce_the_kinematics() {
        let p = Params::default();
        for (mode, a, b) in [
            (Mode::Flat, 0.0, 1.3),
            (Mode::Left, 0.04, 1.7),
            (Mode::Right, -0.03, 1.2),
        ] {
            let tfs = transforms(&p, 1.0, 1.0, mode, a, b).transforms;
            let q = point_masses(&p, mode, &State::new(a, b, 0.0, 0.0));
            let tip = apply(&tfs[0], apply(&tfs[1], [p.l, 0.0, 0.0]));
            let right = apply(&tfs[0], [p.f, 0.0, 0.0]);
            let left = apply(&tfs[0], [-p.f, 0.0, 0.0]);
            let (ca, sa) = (a.cos(), a.sin());
            let close = |got: [f64; 3], x: f64, y: f64| {
                (got[0] - x).abs() < 1e-12 && got[1] == 0.0 && (got[2] - y).abs() < 1e-12
            };
            assert!(
                close(tip, q.tip.x, q.tip.y),
                "{mode}: {tip:?} vs {:?}",
                q.tip
            );
            assert!(close(right, q.foot.x + p.f * ca, q.foot.y + p.f * sa));
            assert!(close(left, q.foot.x - p.f * ca, q.foot.y - p.f * sa));
            // The pivot edge stays on the ground.
            let edge = match mode {
                Mode::Right => right,
                _ => left,
            };
            let pv = pivot(&p, mode);
            assert!(close(edge, pv.x, pv.y), "{mode}: pivot {edge:?}");
        }
    }

    /// An exaggerated tilt turns the plate by `k alpha` about the same pivot.
    #[test]
    fn exaggeration_keeps_the_pivot() {
        let p = Params::default();
        let tfs = transforms(&p, 5.0, 0.0, Mode::Left, 0.04, 1.5).transforms;
        let right = apply(&tfs[0], [p.f, 0.0, 0.0]);
        let left = apply(&tfs[0], [-p.f, 0.0, 0.0]);
        assert!(left.iter().all(|c| c.abs() < 1e-12), "{left:?}");
        assert!((right[2] - 2.0 * p.f * 0.2f64.sin()).abs() < 1e-12);
        assert!(check_exaggeration(0.5).is_err() && check_exaggeration(f64::NAN).is_err());
        assert!(title("demo", 5.0).contains("x5"));
    }

    /// The plate and the arm carry their names; the ground's top is at the ground (z = 0).
    #[test]
    fn the_parts_are_named() {
        let p = Params::default();
        let e = entities(&p, "t", 0.0, Mode::Left, false);
        let text = |id: &str| -> Vec<String> {
            let x = e.iter().find(|x| x.id == id).unwrap();
            x.texts.iter().map(|t| t.text.clone()).collect()
        };
        assert_eq!(text("plate"), ["plate"]);
        assert_eq!(text("arm"), ["arm"]);
        let ground = &e.iter().find(|x| x.id == "ground").unwrap().cubes[0];
        let top = ground.pose.unwrap().position.unwrap().z + 0.5 * ground.size.unwrap().z;
        assert!(top.abs() < 1e-12, "{top}");
    }

    /// A landing from a left tilt strikes the right edge, and from a right tilt the left edge.
    #[test]
    fn the_landing_edge_is_opposite_the_pivot() {
        let p = Params::default();
        let x = |m| {
            landing_flash(&p, 1.0, m).spheres[0]
                .pose
                .unwrap()
                .position
                .unwrap()
                .x
        };
        assert_eq!(x(Mode::Left), 2.0 * p.f);
        assert_eq!(x(Mode::Right), 0.0);
    }
}
