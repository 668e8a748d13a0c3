//! Contacts against the known answers: rebound height, sliding distance, no tunnelling, no
//! energy gained, no penetration, and the edge cases where a direction is undefined.

use glam::DVec3;

use super::*;
use crate::solver::bodies::Lattice;
use crate::solver::integrators::IntegratorKind;
use crate::solver::model::{Model, SpringParams};
use crate::solver::simulation::{Config, Simulation};

fn plane(friction: f64, restitution: f64) -> Collider {
    Collider {
        shape: Shape::Plane { point: DVec3::ZERO, normal: DVec3::Y },
        friction,
        restitution,
        motion: None,
    }
}

/// One free particle of 1 kg at `position` with `velocity`.
fn particle(position: DVec3, velocity: DVec3) -> Model {
    let mut m = Model::default();
    m.add_particles([position], |_| 1.0, velocity);
    m
}

/// What the response reads of a particle given the carried friction `friction`, neither held nor
/// stuck.
fn given_friction(friction: Vec3<f64>) -> Given<f64> {
    Given { friction, scale: 1.0, load: 0.0, stuck: false }
}

fn config(integrator: IntegratorKind, dt: f64, colliders: Vec<Collider>) -> Config {
    Config { integrator, dt, colliders, ..Config::default() }
}

#[test]
fn a_dropped_particle_rebounds_to_restitution_squared_of_its_height() {
    for integrator in [IntegratorKind::SymplecticEuler, IntegratorKind::Verlet, IntegratorKind::Rk4] {
        for e in [0.5, 0.8] {
            let model = particle(DVec3::new(0.0, 1.0, 0.0), DVec3::ZERO);
            let mut sim = Simulation::<f64>::new(&model, &config(integrator, 1e-4, vec![plane(0.3, e)]));
            // Fall (0.45 s), bounce, and rise: the peak comes before 1.3 s for e ≤ 0.8.
            let mut bounced = false;
            let mut peak: f64 = 0.0;
            for _ in 0..13_000 {
                sim.step().unwrap();
                let (x, v) = (sim.state().positions.get(0), sim.state().velocities.get(0));
                assert!(x.y >= -1e-12, "{integrator:?} below the plane: {}", x.y);
                bounced |= v.y > 0.0;
                if bounced {
                    peak = peak.max(x.y);
                }
            }
            let expected = e * e;
            assert!(
                (peak - expected).abs() < 0.02 * expected,
                "{integrator:?}, e {e}: peak {peak}, expected {expected}"
            );
        }
    }
}

#[test]
fn a_box_sliding_with_friction_stops_after_v_squared_over_two_mu_g() {
    let (mu, speed, g) = (0.4, 2.0, 9.81);
    let mut model = Model::default();
    model.add_lattice(&Lattice {
        size: [0.1, 0.1, 0.1],
        resolution: [2, 2, 2],
        center: DVec3::new(0.0, 0.05, 0.0),
        mass: 1.0,
        velocity: DVec3::new(speed, 0.0, 0.0),
        structural: SpringParams { stiffness: 2e4, damping: 5.0 },
        shear: SpringParams { stiffness: 2e4, damping: 5.0 },
        bending: SpringParams { stiffness: 2e4, damping: 5.0 },
        pins: vec![],
    });
    let start = centre_x(&model.positions);
    let mut sim =
        Simulation::<f64>::new(&model, &config(IntegratorKind::SymplecticEuler, 1e-4, vec![plane(mu, 0.0)]));
    for _ in 0..10_000 {
        sim.step().unwrap();
    }
    let positions: Vec<DVec3> = sim.state().positions.iter().map(|p| p.to_dvec3()).collect();
    let travelled = centre_x(&positions) - start;
    let expected = speed * speed / (2.0 * mu * g);
    assert!((travelled - expected).abs() < 0.02 * expected, "travelled {travelled}, expected {expected}");
    assert!(sim.state().velocities.iter().all(|v| v.length() < 1e-3), "still moving");
}

fn centre_x(positions: &[DVec3]) -> f64 {
    positions.iter().map(|p| p.x).sum::<f64>() / positions.len() as f64
}

#[test]
fn a_particle_at_100_m_s_stops_at_a_plane_and_at_a_sphere() {
    let dt = 1.0 / 60.0;
    // Straight down onto the floor from 1 m: one step takes it 1.67 m.
    let model = particle(DVec3::new(0.0, 1.0, 0.0), DVec3::new(0.0, -100.0, 0.0));
    let mut sim =
        Simulation::<f64>::new(&model, &config(IntegratorKind::SymplecticEuler, dt, vec![plane(0.3, 0.0)]));
    sim.step().unwrap();
    assert!(sim.state().positions.get(0).y.abs() < 1e-12, "{:?}", sim.state().positions.get(0));
    assert!(sim.state().velocities.get(0).y.abs() < 1e-12);

    // Through a ball of radius 0.3 m in one step: it stops on the near side.
    let ball = Collider {
        shape: Shape::Sphere { center: DVec3::ZERO, radius: 0.3 },
        friction: 0.0,
        restitution: 0.0,
        motion: None,
    };
    for start in [DVec3::new(-0.8, 0.0, 0.0), DVec3::new(-0.4, 0.05, 0.0)] {
        let model = particle(start, DVec3::new(100.0, 0.0, 0.0));
        let mut sim = Simulation::<f64>::new(
            &model,
            &Config {
                gravity: DVec3::ZERO,
                ..config(IntegratorKind::SymplecticEuler, dt, vec![ball.clone()])
            },
        );
        sim.step().unwrap();
        let x = sim.state().positions.get(0).to_dvec3();
        assert!(x.x < 0.0, "went through to {x:?}");
        assert!((x.length() - 0.3).abs() < 1e-12, "{x:?}");
    }
}

fn all_shapes() -> Vec<Shape> {
    vec![
        Shape::Plane { point: DVec3::new(0.0, 0.1, 0.0), normal: DVec3::new(0.2, 1.0, -0.1) },
        Shape::Sphere { center: DVec3::new(0.1, 0.0, 0.0), radius: 0.5 },
        Shape::Box { center: DVec3::new(0.0, 0.0, 0.1), half_extents: DVec3::new(0.4, 0.3, 0.5) },
        Shape::Cylinder { center: DVec3::ZERO, radius: 0.5, height: 0.4 },
    ]
}

/// A deterministic scatter of points and velocities around the origin.
fn scatter(count: usize) -> (Vectors<f64>, Vectors<f64>) {
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let (points, velocities): (Vec<_>, Vec<_>) = (0..count)
        .map(|_| (Vec3::new(next(), next(), next()), Vec3::new(next(), next(), next()) * 3.0))
        .unzip();
    (points.into_iter().collect(), velocities.into_iter().collect())
}

#[test]
fn contacts_never_add_kinetic_energy_and_leave_no_particle_inside() {
    for shape in all_shapes() {
        for (friction, restitution) in [(0.0, 1.0), (0.3, 0.0), (2.0, 0.5), (0.0, 0.0)] {
            let (positions, velocities) = scatter(2000);
            let contacts = Contacts::<f64>::new(
                &[Collider { shape: shape.clone(), friction, restitution, motion: None }],
                positions.len(),
            )
            .unwrap();
            let mut contacts = contacts;
            contacts.begin_step(&positions, &mut velocities.clone(), 1e-3);
            let mut state = State { positions: positions.clone(), velocities: velocities.clone() };
            contacts.resolve(&mut state, &vec![1.0; positions.len()]);
            for (p, (v0, v1)) in velocities.iter().zip(state.velocities.iter()).enumerate() {
                let (before, after) = (v0.length_squared(), v1.length_squared());
                assert!(
                    after <= before * (1.0 + 1e-12),
                    "{shape:?} gained energy at {p}: {before} -> {after}"
                );
                let depth = shape.signed_distance(state.positions.get(p).to_dvec3());
                assert!(depth > -1e-12, "{shape:?}: particle {p} still {depth} inside");
            }
        }
    }
}

#[test]
fn friction_stops_slow_sliding_and_only_slows_fast_sliding() {
    let n = Vec3::new(0.0, 1.0, 0.0);
    let none = Vec3::ZERO;
    let mut slow = Vec3::new(0.1, -1.0, 0.0);
    respond(&mut slow, n, 0.5, 0.0, None);
    assert_eq!(slow, Vec3::new(0.0, 0.0, 0.0));
    let mut fast = Vec3::new(3.0, -1.0, 4.0);
    respond(&mut fast, n, 0.5, 0.5, None);
    // Δv_n = 1.5, so the tangential speed 5 drops by 0.75; the normal speed is -e v_n = 0.5.
    let expected = Vec3::new(3.0, 0.0, 4.0) * (4.25 / 5.0) + Vec3::new(0.0, 0.5, 0.0);
    assert!((fast - expected).length() < 1e-15, "{fast:?}");
    // A separating particle is untouched, and carries nothing on.
    let mut leaving = Vec3::new(1.0, 0.5, 0.0);
    let carried =
        respond(&mut leaving, n, 0.5, 0.5, Some(given_friction(Vec3::new(-0.01, 0.0, 0.0)))).carried_on(none);
    assert_eq!((leaving, carried), (Vec3::new(1.0, 0.5, 0.0), none));
}

#[test]
fn friction_carries_its_steady_part_into_the_next_step() {
    // μ = 0.5 and Δv_n = 0.1: friction can change the tangential velocity by 0.05 in a step.
    let n = Vec3::new(0.0, 1.0, 0.0);
    let close = |a: Vec3<f64>, b: Vec3<f64>| (a - b).length() < 1e-15;
    // Held: the friction given at the start balanced the step's push exactly; it stays still and
    // carries the same friction on.
    let mut held = Vec3::new(0.0, -0.1, 0.0);
    let carried = respond(&mut held, n, 0.5, 0.0, Some(given_friction(Vec3::new(-0.02, 0.0, 0.0))))
        .carried_on(Vec3::ZERO);
    assert!(close(held, Vec3::ZERO) && close(carried, Vec3::new(-0.02, 0.0, 0.0)), "{held:?} {carried:?}");
    // Arriving at 0.03 along x and pushed 0.01 further in the step: stopped (0.04 is within
    // 0.05), but only the push, not the stopping of its arrival, is carried on.
    let mut arriving = Vec3::new(0.04, -0.1, 0.0);
    let carried = respond(&mut arriving, n, 0.5, 0.0, Some(given_friction(Vec3::ZERO)))
        .carried_on(Vec3::new(0.03, 0.0, 0.0));
    assert!(
        close(arriving, Vec3::ZERO) && close(carried, Vec3::new(-0.01, 0.0, 0.0)),
        "{arriving:?} {carried:?}"
    );
    // Sliding at 1 with the kinetic friction -0.05 given at the start and pushed 0.01 in the
    // step: it ends at 0.96, its whole friction of the step 0.05, and carries on the friction that
    // balances the push. The normal part of the carried friction is dropped.
    let mut sliding = Vec3::new(0.96, -0.1, 0.0);
    let carried = respond(&mut sliding, n, 0.5, 0.0, Some(given_friction(Vec3::new(-0.05, 0.3, 0.0))))
        .carried_on(Vec3::new(1.0, 0.0, 0.0));
    assert!(
        close(sliding, Vec3::new(0.96, 0.0, 0.0)) && close(carried, Vec3::new(-0.01, 0.0, 0.0)),
        "{sliding:?} {carried:?}"
    );
}

#[test]
fn particles_with_no_defined_push_direction_get_a_finite_one() {
    let at_centre = ShapeIn::<f64>::new(&Shape::Sphere { center: DVec3::new(1.0, 2.0, 3.0), radius: 0.5 })
        .inside(Vec3::new(1.0, 2.0, 3.0))
        .unwrap();
    assert_eq!(at_centre.point, Vec3::new(1.0, 2.5, 3.0));
    // On the axis of a tall cylinder the side is nearest: out along +x.
    let on_axis = ShapeIn::<f64>::new(&Shape::Cylinder { center: DVec3::ZERO, radius: 0.1, height: 2.0 })
        .inside(Vec3::new(0.0, 0.2, 0.0))
        .unwrap();
    assert_eq!(on_axis.point, Vec3::new(0.1, 0.2, 0.0));
    assert_eq!(on_axis.normal, Vec3::new(1.0, 0.0, 0.0));
    // At the centre of a cube, a face.
    let in_cube = ShapeIn::<f64>::new(&Shape::Box { center: DVec3::ZERO, half_extents: DVec3::splat(0.5) })
        .inside(Vec3::ZERO)
        .unwrap();
    assert!(in_cube.point.is_finite() && (in_cube.normal.length() - 1.0).abs() < 1e-15);
}

#[test]
fn signed_distances_match_the_geometry() {
    let table = Shape::Cylinder { center: DVec3::new(0.0, 0.5, 0.0), radius: 0.5, height: 1.0 };
    // Expected distances worked by hand from the shapes: above the top, beside the side, inside
    // nearer the top than the side, and past the rim (a 3-4-5 triangle to the top edge).
    assert!((table.signed_distance(DVec3::new(0.0, 1.2, 0.0)) - 0.2).abs() < 1e-15);
    assert!((table.signed_distance(DVec3::new(0.8, 0.5, 0.0)) - 0.3).abs() < 1e-15);
    assert!((table.signed_distance(DVec3::new(0.1, 0.9, 0.0)) + 0.1).abs() < 1e-15);
    assert!((table.signed_distance(DVec3::new(0.8, 1.4, 0.0)) - 0.5).abs() < 1e-15);
    let cube = Shape::Box { center: DVec3::ZERO, half_extents: DVec3::splat(1.0) };
    // Inside, half a unit from the nearest face; outside, 3-4-5 from the corner (1, 1).
    assert!((cube.signed_distance(DVec3::new(0.5, 0.0, 0.0)) + 0.5).abs() < 1e-15);
    assert!((cube.signed_distance(DVec3::new(4.0, 5.0, 0.0)) - 5.0).abs() < 1e-15);
}

#[test]
fn particles_that_start_inside_are_projected_out_and_pinned_ones_never_move() {
    let mut model = Model::default();
    model.add_particles(
        [DVec3::new(0.0, -0.5, 0.0), DVec3::new(0.3, -0.2, 0.0), DVec3::new(0.0, 2.0, 0.0)],
        |_| 1.0,
        DVec3::ZERO,
    );
    model.pin(1);
    let sim =
        Simulation::<f64>::new(&model, &config(IntegratorKind::SymplecticEuler, 1e-3, vec![plane(0.3, 0.0)]));
    assert_eq!(sim.state().positions.get(0), Vec3::new(0.0, 0.0, 0.0));
    assert_eq!(sim.state().positions.get(1), Vec3::new(0.3, -0.2, 0.0));
    let mut sim = sim;
    for _ in 0..100 {
        sim.step().unwrap();
    }
    assert_eq!(sim.state().positions.get(1), Vec3::new(0.3, -0.2, 0.0));
    assert!(sim.state().positions.get(0).y.abs() < 1e-12);
}

#[test]
fn colliders_are_stages_only_when_present_each_type_named_once() {
    let model = particle(DVec3::new(0.0, 1.0, 0.0), DVec3::ZERO);
    let none = Simulation::<f64>::new(&model, &config(IntegratorKind::SymplecticEuler, 1e-3, vec![]));
    assert_eq!(none.stages(), ["gravity"]);
    let ball = Collider {
        shape: Shape::Sphere { center: DVec3::ZERO, radius: 0.1 },
        friction: 0.3,
        restitution: 0.0,
        motion: None,
    };
    let colliders = vec![ball.clone(), plane(0.3, 0.0), ball];
    let both = Simulation::<f64>::new(&model, &config(IntegratorKind::SymplecticEuler, 1e-3, colliders));
    assert_eq!(both.stages(), ["gravity", "sphere", "plane"]);
    let shapes = all_shapes().into_iter().map(|shape| Collider {
        shape,
        friction: 0.3,
        restitution: 0.0,
        motion: None,
    });
    let all =
        Simulation::<f64>::new(&model, &config(IntegratorKind::SymplecticEuler, 1e-3, shapes.collect()));
    assert_eq!(all.stages(), ["gravity", "plane", "sphere", "box", "cylinder"]);
}

#[test]
fn single_precision_contacts_hold_as_well() {
    let ball = Collider {
        shape: Shape::Sphere { center: DVec3::ZERO, radius: 0.3 },
        friction: 0.5,
        restitution: 0.0,
        motion: None,
    };
    let mut model = Model::default();
    model.add_particles((0..20).map(|k| DVec3::new(0.01 * k as f64, 1.0, 0.0)), |_| 0.1, DVec3::ZERO);
    let mut sim = Simulation::<f32>::new(
        &model,
        &config(IntegratorKind::SymplecticEuler, 1e-3, vec![ball.clone(), plane(0.5, 0.0)]),
    );
    for _ in 0..2000 {
        sim.step().unwrap();
        for x in sim.state().positions.iter() {
            let x = x.to_dvec3();
            assert!(ball.shape.signed_distance(x) > -1e-6 && x.y > -1e-6, "{x:?}");
        }
    }
}

#[test]
fn particles_resolved_in_bands_and_lanes_end_as_each_resolved_alone() {
    resolved_in_bands_and_lanes_as_alone::<f32>();
    resolved_in_bands_and_lanes_as_alone::<f64>();
}

fn resolved_in_bands_and_lanes_as_alone<T: Real>() {
    // Thousands of particles moving through and past every kind of shape (enough for two bands,
    // and a count that leaves a partial block), some pinned: the banded, laned pass must give
    // every particle the bits of the plain loop over particles and colliders.
    let colliders: Vec<Collider> = [
        Shape::Plane { point: DVec3::new(0.0, -0.5, 0.0), normal: DVec3::new(0.1, 1.0, 0.0) },
        Shape::Sphere { center: DVec3::ZERO, radius: 0.4 },
        Shape::Box { center: DVec3::new(0.6, 0.0, 0.0), half_extents: DVec3::new(0.2, 0.3, 0.2) },
        Shape::Cylinder { center: DVec3::new(-0.6, 0.0, 0.0), radius: 0.25, height: 0.6 },
    ]
    .into_iter()
    .map(|shape| Collider { shape, friction: 0.3, restitution: 0.2, motion: None })
    .collect();
    let n = 2 * crate::solver::parallel::MIN_PARTICLES_PER_BAND + 5;
    let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
    let mut random = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut point = || DVec3::new(random(), random(), random());
    let start: Vectors<T> = (0..n).map(|_| Vec3::from_dvec3(point())).collect();
    let state = State {
        positions: start.iter().map(|x| x + Vec3::from_dvec3(point() * 0.3)).collect(),
        velocities: (0..n).map(|_| Vec3::from_dvec3(point())).collect(),
    };
    let inverse_masses: Vec<T> = (0..n).map(|p| if p % 97 == 0 { T::ZERO } else { T::ONE }).collect();
    let mut contacts = Contacts::<T>::new(&colliders, n).unwrap();
    contacts.begin_step(&start, &mut state.velocities.clone(), T::from_f64(1e-3));

    let mut expected = state.clone();
    let mut expected_touched = false;
    for p in (0..n).filter(|&p| inverse_masses[p] != T::ZERO) {
        for c in &contacts.colliders {
            if let Some(surface) = c.shape.contact(start.get(p), expected.positions.get(p), None) {
                expected.positions.set(p, surface.point);
                let mut v = expected.velocities.get(p);
                respond(&mut v, surface.normal, c.friction, c.restitution, None);
                expected.velocities.set(p, v);
                expected_touched = true;
            }
        }
    }
    let touched_count = (0..n).filter(|&p| expected.positions.get(p) != state.positions.get(p)).count();
    assert!(touched_count > n / 10, "only {touched_count} of {n} particles touch a shape");

    let mut actual = state.clone();
    let touched = crate::solver::parallel::install(|| contacts.resolve(&mut actual, &inverse_masses));
    assert_eq!(touched, expected_touched);
    assert!(actual.positions == expected.positions && actual.velocities == expected.velocities);
}

#[test]
fn the_start_of_a_step_is_kept_only_for_colliders_that_test_paths() {
    let mut positions = Vectors::<f64>::zeros(3);
    for p in 0..3 {
        positions.set(p, Vec3::new(p as f64, 1.0, 0.5));
    }
    let fixed = |shape| Collider { shape, friction: 0.3, restitution: 0.0, motion: None };
    let unit_box = Shape::Box { center: DVec3::ZERO, half_extents: DVec3::ONE };
    let cylinder = Shape::Cylinder { center: DVec3::ZERO, radius: 1.0, height: 1.0 };
    let ball = Shape::Sphere { center: DVec3::ZERO, radius: 1.0 };
    let sliding =
        Motion::Velocity { start: Rigid::IDENTITY, velocity: DVec3::X, angular_velocity: DVec3::ZERO };
    let moving_plane = Collider { motion: Some(sliding), ..plane(0.3, 0.0) };
    for (colliders, swept) in [
        (vec![plane(0.3, 0.0), fixed(unit_box), fixed(cylinder)], false),
        (vec![plane(0.3, 0.0), fixed(ball)], true),
        (vec![moving_plane], true),
    ] {
        let mut contacts = Contacts::<f64>::new(&colliders, 3).expect("there are colliders");
        contacts.begin_step(&positions, &mut Vectors::zeros(3), 1e-3);
        let kept: Vec<Vec3<f64>> = contacts.start.iter().collect();
        let expected = if swept { positions.iter().collect() } else { vec![Vec3::ZERO; 3] };
        assert_eq!(kept, expected, "{colliders:?}");
    }
}

/// Which contacts the next implicit solve holds, against a floor with μ 0.5, over two steps of
/// 1/60 s: every particle the projection stops is held, and one that friction stopped is stuck to
/// the point where it stopped; one held before stays held while it lies within reach of the
/// surface without leaving it, and is let go once it leaves or lies beyond reach. A stuck
/// particle's friction is its anchor spring's impulse, bounded by that impulse's normal part and
/// the projection's: within Coulomb's cone it stays stuck, beyond it it slides.
#[test]
fn a_stopped_particle_is_held_in_the_next_solve_until_it_leaves_the_surface() {
    let h = 1.0 / 60.0;
    let mut contacts = Contacts::<f64>::new(&[plane(0.5, 0.0)], 6).unwrap().with_carried_friction();
    let up = Vec3::new(0.0, 1.0, 0.0);
    let at = |x: f64, y: f64| Vec3::new(x, y, 0.0);
    let mut state = State {
        positions: (0..6).map(|_| at(0.0, -1e-4)).collect(),
        velocities: (0..6).map(|p| if p == 5 { Vec3::ZERO } else { Vec3::new(0.0, -0.1, 0.0) }).collect(),
    };
    contacts.begin_step(&state.positions.clone(), &mut state.velocities, h);
    contacts.resolve(&mut state, &[1.0; 6]);
    let holds = contacts.held().unwrap();
    let held: Vec<Vec3<f64>> = holds.normals.iter().collect();
    assert_eq!(held, [up, up, up, up, up, Vec3::ZERO], "the particle at rest was not stopped");
    let (anchors, stuck) = holds.anchored.unwrap();
    assert_eq!(stuck, [true, true, true, true, true, false]);
    assert!((0..5).all(|p| anchors.get(p) == Vec3::ZERO));

    // The solve took the stuck particles 0 and 4 from their anchor (the origin) 1e-5 m into the
    // floor and sideways, particle 0 by a fifth of that and particle 4 by four fifths: friction
    // holds them while the sideways part is within `μ` of the inward one.
    let depth = 1e-5;
    let pushed = |sideways: f64| (at(sideways * depth, -depth), at(sideways * depth, -depth) * (1.0 / h));
    let next = [
        pushed(0.2),                                    // stuck, within the cone
        (at(0.0, 1e-7), Vec3::ZERO),                    // lying on the surface
        (at(0.0, 1e-7), Vec3::new(0.0, 0.01, 0.0)),     // leaving it
        (at(0.0, 2e-4), Vec3::ZERO),                    // beyond reach
        pushed(0.8),                                    // stuck, beyond the cone
        (at(0.0, -1e-6), Vec3::new(0.05, -0.001, 0.0)), // not held, sliding in
    ];
    contacts.begin_step(&state.positions.clone(), &mut state.velocities, h);
    for (p, (x, v)) in next.into_iter().enumerate() {
        state.positions.set(p, x);
        state.velocities.set(p, v);
    }
    contacts.resolve(&mut state, &[1.0; 6]);
    let holds = contacts.held().unwrap();
    let held: Vec<Vec3<f64>> = holds.normals.iter().collect();
    assert_eq!(held, [up, up, Vec3::ZERO, Vec3::ZERO, up, up]);
    let (anchors, stuck) = holds.anchored.unwrap();
    assert_eq!(stuck, [true, true, false, false, false, false]);
    assert_eq!((anchors.get(0), anchors.get(1)), (Vec3::ZERO, Vec3::ZERO));
    assert_eq!(state.velocities.get(0), Vec3::ZERO);
    // Particle 4 slides: it keeps the velocity the solve gave it (its anchor spring was its
    // friction there), and is held along the normal from now on.
    assert_eq!(state.velocities.get(4), Vec3::new(pushed(0.8).1.x, 0.0, 0.0));
    // Friction can take 0.5 · 0.001 from the unheld particle's 0.05.
    assert!((state.velocities.get(5).x - 0.0495).abs() < 1e-15, "{:?}", state.velocities.get(5));
}

/// A particle of 1 kg resting on a floor with μ 0.5, tied by a damped spring of 100 N/m to a
/// pinned particle that starts pulling it along the floor at 0.1 m/s after a second, stepped by
/// implicit Euler at 1/60 s and by symplectic Euler at 1 ms. Before the pull static friction holds it still; pulled, it slides behind the pin at
/// the pin's speed with the spring stretched by `μ m g / k` (49 mm), as Coulomb's kinetic friction
/// says. A model of static friction that held the particle harder, or dragged on its motion once
/// it slides, would leave it further behind.
#[test]
fn a_resting_particle_pulled_beyond_friction_slides_with_coulombs_kinetic_friction() {
    use crate::solver::bodies::Chain;
    use crate::solver::motion::{Keyframe, Motion, Rigid};
    use crate::solver::pin_motion::PinMotion;
    let (mu, g, k, speed, rest) = (0.5, 9.81, 100.0, 0.1, 0.2);
    let mut model = Model::default();
    model.add_chain(&Chain {
        start: DVec3::ZERO,
        end: DVec3::new(rest, 0.0, 0.0),
        count: 2,
        mass: 2.0,
        velocity: DVec3::ZERO,
        spring: SpringParams { stiffness: k, damping: 4.0 },
        rest_length: None,
        pins: vec![1],
    });
    let pulled = |t: f64| Keyframe {
        t,
        transform: Rigid { translation: DVec3::new(speed * (t - 1.0).max(0.0), 0.0, 0.0), ..Rigid::IDENTITY },
    };
    let motion = Motion::Keyframes(vec![pulled(0.0), pulled(1.0), pulled(10.0)]);
    let pins = PinMotion { particles: vec![1], centre: DVec3::new(rest, 0.0, 0.0), motion };
    for (integrator, steps_per_second) in
        [(IntegratorKind::ImplicitEuler, 60), (IntegratorKind::SymplecticEuler, 1000)]
    {
        let mut config = config(integrator, 1.0 / steps_per_second as f64, vec![plane(mu, 0.0)]);
        config.pin_motions = vec![pins.clone()];
        let mut sim = Simulation::<f64>::new(&model, &config);
        for _ in 0..steps_per_second {
            sim.step().unwrap();
        }
        let still = sim.state().positions.get(0);
        assert!(still.x.abs() < 1e-6 && still.y.abs() < 1e-6, "{integrator:?}: {still:?}");
        for _ in 0..3 * steps_per_second {
            sim.step().unwrap();
        }
        // Its speed over the last second: within a step an explicit step's speed swings by the
        // friction it takes, `μ g h`.
        let before = sim.state().positions.get(0);
        for _ in 0..steps_per_second {
            sim.step().unwrap();
        }
        let x = sim.state().positions.get(0);
        let v = x - before;
        let stretch = sim.state().positions.get(1).x - x.x - rest;
        let expected = mu * 1.0 * g / k;
        assert!(
            (stretch - expected).abs() < 0.02 * expected,
            "{integrator:?}: stretched {stretch} m, not {expected}"
        );
        assert!((v.x - speed).abs() < 0.02 * speed && x.y.abs() < 1e-6, "{integrator:?}: {x:?} {v:?}");
    }
}
