//! Rigid motions over time: where a moving collider (or a body's pinned particles) is at time
//! `t`, as a rotation followed by a translation.
//!
//! A motion is either keyframes, piecewise linear in translation and spherical-linear (slerp)
//! in rotation, held before the first key and after the last; or a constant velocity and angular
//! velocity from a starting placement, `x(t) = translation + v t + exp(ω t) · rotation · x`.

use glam::{DQuat, DVec3};

/// A rigid transform: rotate about the origin, then translate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid {
    /// Displacement, in metres.
    pub translation: DVec3,
    /// Unit rotation.
    pub rotation: DQuat,
}

impl Rigid {
    /// The transform that moves nothing.
    pub const IDENTITY: Self = Self { translation: DVec3::ZERO, rotation: DQuat::IDENTITY };

    /// Where the point `x` goes.
    pub fn point(&self, x: DVec3) -> DVec3 {
        self.translation + self.rotation * x
    }

    /// Where the point `x` came from: the inverse transform.
    pub fn inverse_point(&self, x: DVec3) -> DVec3 {
        self.rotation.inverse() * (x - self.translation)
    }
}

/// One key of a keyframed motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyframe {
    /// Time, in seconds.
    pub t: f64,
    /// The transform from then on towards the next key.
    pub transform: Rigid,
}

/// How a rigid thing moves.
#[derive(Clone, Debug, PartialEq)]
pub enum Motion {
    /// Keyframes in increasing time (at least one).
    Keyframes(Vec<Keyframe>),
    /// A constant velocity and angular velocity from a starting transform.
    Velocity {
        /// The transform at time 0.
        start: Rigid,
        /// Velocity of the origin, in m/s.
        velocity: DVec3,
        /// Angular velocity, in rad/s (its direction the axis, right-handed).
        angular_velocity: DVec3,
    },
}

impl Motion {
    /// The transform at time `t`.
    pub fn at(&self, t: f64) -> Rigid {
        match self {
            Self::Keyframes(keys) => {
                let Some(first) = keys.first() else { return Rigid::IDENTITY };
                let next = keys.partition_point(|k| k.t <= t);
                if next == 0 {
                    return first.transform;
                }
                let Some(after) = keys.get(next) else { return keys[next - 1].transform };
                let before = keys[next - 1];
                let span = after.t - before.t;
                let s = if span > 0.0 { ((t - before.t) / span).clamp(0.0, 1.0) } else { 1.0 };
                Rigid {
                    translation: before.transform.translation.lerp(after.transform.translation, s),
                    rotation: before.transform.rotation.slerp(after.transform.rotation, s).normalize(),
                }
            }
            Self::Velocity { start, velocity, angular_velocity } => {
                let turned = DQuat::from_scaled_axis(*angular_velocity * t);
                Rigid {
                    translation: start.translation + *velocity * t,
                    rotation: (turned * start.rotation).normalize(),
                }
            }
        }
    }
}

impl Motion {
    /// An upper bound on the speed of any point within `reach` of the origin of the scene's
    /// coordinates that moves with it (keyframes: over their fastest span, linear and angular
    /// speed added; a velocity: its own).
    pub fn peak_speed(&self, reach: f64) -> f64 {
        match self {
            Self::Keyframes(keys) => keys
                .windows(2)
                .filter(|pair| pair[1].t > pair[0].t)
                .map(|pair| {
                    let (a, b) = (pair[0].transform, pair[1].transform);
                    let span = pair[1].t - pair[0].t;
                    let lever = reach + a.translation.length().max(b.translation.length());
                    ((b.translation - a.translation).length() + a.rotation.angle_between(b.rotation) * lever)
                        / span
                })
                .fold(0.0, f64::max),
            Self::Velocity { start, velocity, angular_velocity } => {
                velocity.length() + angular_velocity.length() * (reach + start.translation.length())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keyframes_interpolate_linearly_and_by_slerp_and_hold_at_both_ends() {
        let quarter = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2);
        let keys = Motion::Keyframes(vec![
            Keyframe { t: 1.0, transform: Rigid { translation: DVec3::ZERO, rotation: DQuat::IDENTITY } },
            Keyframe {
                t: 3.0,
                transform: Rigid { translation: DVec3::new(2.0, 0.0, 0.0), rotation: quarter },
            },
        ]);
        assert_eq!(keys.at(0.0), Rigid::IDENTITY);
        let middle = keys.at(2.0);
        assert!((middle.translation - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-15);
        // Halfway through a quarter turn is an eighth turn.
        let eighth = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_4);
        assert!(middle.rotation.angle_between(eighth) < 1e-12);
        assert_eq!(keys.at(10.0).translation, DVec3::new(2.0, 0.0, 0.0));
    }

    #[test]
    fn a_velocity_moves_and_turns_at_its_rates() {
        let start = Rigid { translation: DVec3::new(0.0, 1.0, 0.0), rotation: DQuat::IDENTITY };
        let motion = Motion::Velocity {
            start,
            velocity: DVec3::new(2.0, 0.0, 0.0),
            angular_velocity: DVec3::new(0.0, 0.5, 0.0),
        };
        let at = motion.at(2.0);
        assert_eq!(at.translation, DVec3::new(4.0, 1.0, 0.0));
        // One radian about y in two seconds: the point (1, 0, 0) turns to (cos 1, 0, -sin 1).
        let x = at.rotation * DVec3::X;
        assert!((x - DVec3::new(1f64.cos(), 0.0, -(1f64.sin()))).length() < 1e-12, "{x}");
    }
}
