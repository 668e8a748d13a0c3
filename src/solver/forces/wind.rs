//! Wind: the force of moving air on a surface, as a force in the force evaluation.
//!
//! The air moves with velocity `u(x, t)`: the scene's `velocity`, optionally scaled by a gust
//! `1 + A sin(2π (f t - ŵ·x / λ))`, a wave of relative amplitude `A`, frequency `f` and wavelength
//! `λ` travelling downwind (`ŵ` is the wind's direction). Two models turn it into forces:
//!
//! - `viscous`, per vertex: `f = c [n·(u - v)] n` with `n` the unit vertex normal (area-weighted
//!   from the triangles around the vertex), `c` in N·s/m. A vertex on no triangle feels nothing.
//! - `aerodynamic`, per triangle: `f = c A [n·(u - v̄)] n` with `A` the triangle's area, `n` its
//!   unit normal and `v̄` its mean velocity, `u` taken at its centroid, `c` in N·s/m³; a third of
//!   `f` goes to each vertex. A collapsed triangle (zero area) feels nothing.
//!
//! Both act only along the normal, so air sliding along a surface exerts no force. The vertex
//! normals of the viscous model live in a buffer made once, when the simulation is built.

#![allow(clippy::neg_cmp_op_on_partial_ord, reason = "written so that a NaN fails each test")]

use glam::DVec3;

use crate::solver::math::real::Real;
use crate::solver::math::vec3::Vec3;
use crate::solver::math::vectors::Vectors;
use crate::solver::normals;

/// How wind turns into forces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WindModel {
    /// Per vertex, along the vertex normal.
    Viscous,
    /// Per triangle, area-weighted, shared by its three vertices.
    Aerodynamic,
}

impl WindModel {
    /// The name the public contract uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::Viscous => "viscous",
            Self::Aerodynamic => "aerodynamic",
        }
    }
}

/// A travelling wave that scales the wind in space and time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gust {
    /// Relative amplitude `A` (at least 0): the wind speed swings by `±A` of its mean.
    pub amplitude: f64,
    /// Frequency `f`, in Hz (at least 0).
    pub frequency: f64,
    /// Wavelength `λ` along the wind, in metres (positive).
    pub wavelength: f64,
}

/// The wind of a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindConfig {
    /// How the air's motion becomes forces.
    pub model: WindModel,
    /// The air's mean velocity, in m/s.
    pub velocity: DVec3,
    /// The drag coefficient `c` (N·s/m for `viscous`, N·s/m³ for `aerodynamic`; at least 0).
    pub coefficient: f64,
    /// Variation in space and time, if any.
    pub gust: Option<Gust>,
}

impl WindConfig {
    /// The fastest the air ever moves, in m/s: the mean speed times `1 + A`.
    pub fn peak_speed(&self) -> f64 {
        let amplitude = self.gust.map_or(0.0, |g| g.amplitude.abs());
        self.velocity.length() * (1.0 + amplitude)
    }
}

/// The wind stage of a force evaluation, with its scratch.
#[derive(Clone, Debug)]
pub(crate) struct Wind<T> {
    model: WindModel,
    velocity: Vec3<T>,
    coefficient: T,
    gust: Option<Wave>,
    triangles: Vec<[u32; 3]>,
    /// Vertex normals (viscous model only; empty otherwise).
    normals: Vec<Vec3<T>>,
}

/// A gust as a phase `ω t - k·x`.
#[derive(Clone, Copy, Debug)]
struct Wave {
    amplitude: f64,
    angular_frequency: f64,
    wave_vector: DVec3,
}

impl Wave {
    #[inline]
    fn factor<T: Real>(&self, x: Vec3<T>, t: f64) -> T {
        let phase = self.angular_frequency * t - self.wave_vector.dot(x.to_dvec3());
        T::from_f64(1.0 + self.amplitude * phase.sin())
    }
}

impl<T: Real> Wind<T> {
    pub fn new(config: &WindConfig, triangles: &[[u32; 3]], particles: usize) -> Self {
        let tau = std::f64::consts::TAU;
        let speed = config.velocity.length();
        let gust = config.gust.map(|g| Wave {
            amplitude: g.amplitude,
            angular_frequency: tau * g.frequency,
            // Still air has no direction, and nothing to scale: the wave is then flat.
            wave_vector: if speed > 0.0 && g.wavelength > 0.0 {
                config.velocity * (tau / (speed * g.wavelength))
            } else {
                DVec3::ZERO
            },
        });
        let normals = match config.model {
            WindModel::Viscous => vec![Vec3::ZERO; particles],
            WindModel::Aerodynamic => Vec::new(),
        };
        Self {
            model: config.model,
            velocity: Vec3::from_dvec3(config.velocity),
            coefficient: T::from_f64(config.coefficient),
            gust,
            triangles: triangles.to_vec(),
            normals,
        }
    }

    /// The names of the stages wind runs: vertex normals first for the viscous model.
    pub fn stages(&self) -> &'static [&'static str] {
        match self.model {
            WindModel::Viscous => &["normals", "wind"],
            WindModel::Aerodynamic => &["wind"],
        }
    }

    /// The air's velocity at `x` and time `t`.
    #[inline]
    fn air(&self, x: Vec3<T>, t: f64) -> Vec3<T> {
        match &self.gust {
            Some(wave) => self.velocity * wave.factor(x, t),
            None => self.velocity,
        }
    }

    /// Adds the wind force on every particle at state `(x, v)` and time `t`.
    pub fn add_forces(&mut self, x: &Vectors<T>, v: &Vectors<T>, t: f64, forces: &mut Vectors<T>) {
        match self.model {
            WindModel::Viscous => {
                normals::vertex_normals(&self.triangles, x, &mut self.normals);
                for p in 0..x.len() {
                    let n = self.normals[p];
                    let relative = self.air(x.get(p), t) - v.get(p);
                    forces.add(p, n * (self.coefficient * n.dot(relative)));
                }
            }
            WindModel::Aerodynamic => {
                let third = T::ONE / T::from_f64(3.0);
                let half = T::from_f64(0.5);
                for &[a, b, c] in &self.triangles {
                    let (a, b, c) = (a as usize, b as usize, c as usize);
                    // |cross| is twice the area; cross / |cross| the unit normal.
                    let (xa, xb, xc) = (x.get(a), x.get(b), x.get(c));
                    let cross = (xb - xa).cross(xc - xa);
                    let twice_area = cross.length();
                    if !(twice_area > T::ZERO) {
                        continue;
                    }
                    let centroid = (xa + xb + xc) * third;
                    let mean_velocity = (v.get(a) + v.get(b) + v.get(c)) * third;
                    let relative = self.air(centroid, t) - mean_velocity;
                    // c A (n·w) n = c (cross·w) cross / (2 |cross|).
                    let f = cross * (self.coefficient * cross.dot(relative) * half / twice_area);
                    let share = f * third;
                    forces.add(a, share);
                    forces.add(b, share);
                    forces.add(c, share);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> (Vectors<f64>, Vec<[u32; 3]>) {
        // A unit square in the x-y plane, facing +z.
        let x = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
        ]
        .into_iter()
        .collect();
        (x, vec![[0, 1, 2], [2, 1, 3]])
    }

    fn total(forces: &Vectors<f64>) -> Vec3<f64> {
        forces.iter().fold(Vec3::ZERO, |s, f| s + f)
    }

    #[test]
    fn aerodynamic_force_on_a_square_is_coefficient_times_area_times_normal_speed() {
        let (x, triangles) = square();
        let config = WindConfig {
            model: WindModel::Aerodynamic,
            velocity: DVec3::new(3.0, 0.0, 2.0),
            coefficient: 1.5,
            gust: None,
        };
        let mut wind = Wind::<f64>::new(&config, &triangles, 4);
        let v = std::iter::repeat_n(Vec3::new(0.0, 0.0, 0.5), 4).collect();
        let mut forces = Vectors::zeros(4);
        wind.add_forces(&x, &v, 0.0, &mut forces);
        // Area 1, normal +z, relative normal speed 2 - 0.5: only the z component survives.
        let f = total(&forces);
        assert!((f.z - 1.5 * 1.0 * 1.5).abs() < 1e-12, "{f:?}");
        assert!(f.x.abs() < 1e-12 && f.y.abs() < 1e-12);
    }

    #[test]
    fn viscous_force_follows_vertex_normals_and_ignores_air_along_the_surface() {
        let (x, triangles) = square();
        let config = WindConfig {
            model: WindModel::Viscous,
            velocity: DVec3::new(5.0, 0.0, -2.0),
            coefficient: 0.25,
            gust: None,
        };
        let mut wind = Wind::<f64>::new(&config, &triangles, 4);
        let v = Vectors::zeros(4);
        let mut forces = Vectors::zeros(4);
        wind.add_forces(&x, &v, 0.0, &mut forces);
        for f in forces.iter() {
            assert!((f.z - 0.25 * -2.0).abs() < 1e-12 && f.x.abs() < 1e-12, "{f:?}");
        }
    }

    #[test]
    fn gust_scales_the_wind_as_a_wave_travelling_downwind() {
        let (x, triangles) = square();
        let gust = Gust { amplitude: 0.5, frequency: 2.0, wavelength: 4.0 };
        let config = WindConfig {
            model: WindModel::Viscous,
            velocity: DVec3::new(0.0, 0.0, 1.0),
            coefficient: 1.0,
            gust: Some(gust),
        };
        let mut wind = Wind::<f64>::new(&config, &triangles, 4);
        let v = Vectors::zeros(4);
        let mut forces = Vectors::zeros(4);
        // At t = 1/16 s the phase 2π·2·t is π/4 at z = 0.
        let t = 1.0 / 16.0;
        wind.add_forces(&x, &v, t, &mut forces);
        let expected = 1.0 + 0.5 * (std::f64::consts::FRAC_PI_4).sin();
        assert!((forces.get(0).z - expected).abs() < 1e-12, "{:?}", forces.get(0));
        assert!((config.peak_speed() - 1.5).abs() < 1e-15);
    }

    #[test]
    fn collapsed_triangles_and_lone_vertices_feel_no_wind() {
        let x: Vectors<f64> = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0)]
            .into_iter()
            .collect();
        for model in [WindModel::Viscous, WindModel::Aerodynamic] {
            let config =
                WindConfig { model, velocity: DVec3::new(0.0, 4.0, 1.0), coefficient: 1.0, gust: None };
            let mut wind = Wind::<f64>::new(&config, &[[0, 1, 2]], 3);
            let mut forces = Vectors::zeros(3);
            wind.add_forces(&x, &Vectors::zeros(3), 0.0, &mut forces);
            assert!(forces.iter().all(|f| f == Vec3::ZERO), "{model:?}: {forces:?}");
        }
    }

    fn flag(wind: Option<WindConfig>, gravity: DVec3) -> crate::solver::simulation::Simulation<f64> {
        use crate::solver::bodies::{Cloth, Orientation};
        use crate::solver::integrators::IntegratorKind;
        use crate::solver::model::{Model, SpringParams};
        use crate::solver::simulation::{Config, Simulation};
        let mut model = Model::default();
        let springs = SpringParams { stiffness: 500.0, damping: 0.5 };
        model.add_cloth(&Cloth {
            size: [0.6, 0.4],
            resolution: [8, 6],
            center: glam::DVec3::new(0.0, 1.0, 0.0),
            orientation: Orientation::Vertical,
            mass: 0.1,
            velocity: glam::DVec3::ZERO,
            structural: springs,
            shear: springs,
            bending: springs,
            pins: (0..8).map(|i| [i, 0]).collect(),
        });
        let config = Config {
            integrator: IntegratorKind::Rk4,
            dt: 2e-3,
            drag: 0.2,
            wind,
            gravity,
            ..Config::default()
        };
        Simulation::new(&model, &config)
    }

    #[test]
    fn wind_is_a_stage_only_when_present_and_normals_only_for_the_viscous_model() {
        let g = DVec3::new(0.0, -9.81, 0.0);
        assert_eq!(flag(None, g).stages(), ["gravity", "drag", "springs"]);
        let aerodynamic = WindConfig {
            model: WindModel::Aerodynamic,
            velocity: DVec3::Z * 4.0,
            coefficient: 1.0,
            gust: None,
        };
        assert_eq!(flag(Some(aerodynamic), g).stages(), ["gravity", "drag", "springs", "wind"]);
        let viscous = WindConfig { model: WindModel::Viscous, ..aerodynamic };
        assert_eq!(flag(Some(viscous), g).stages(), ["gravity", "drag", "springs", "normals", "wind"]);
    }

    #[test]
    fn gusty_wind_blows_the_flag_downwind_without_tripping_the_energy_watch() {
        // Without gravity the scene's only energy source is the wind: the watch must budget for it.
        let gust = Gust { amplitude: 1.0, frequency: 3.0, wavelength: 1.0 };
        for model in [WindModel::Viscous, WindModel::Aerodynamic] {
            let wind = WindConfig {
                model,
                velocity: DVec3::new(0.0, 0.0, 30.0),
                coefficient: 0.05,
                gust: Some(gust),
            };
            let mut sim = flag(Some(wind), DVec3::ZERO);
            let mut steps = |count: usize| {
                for _ in 0..count {
                    sim.step().unwrap_or_else(|d| panic!("{model:?}: {d:?}"));
                }
                sim.state().positions.iter().map(|p| p.z).sum::<f64>() / 48.0
            };
            // Where a fluttering flag is at a given later instant depends on rounding: its first
            // 0.2 s is the part of the motion that does not.
            let mean_z = steps(100);
            assert!(mean_z > 0.02, "{model:?}: mean z {mean_z} after 0.2 s");
            let mean_z = steps(400);
            assert!(mean_z.abs() < 0.6, "{model:?}: mean z {mean_z} after 1 s");
        }
    }
}
