use std::f64::consts::{PI, TAU};

use glam::DVec3;

use super::*;
use crate::solver::{Disk, Model, Orientation, SpringParams};

/// A 30 cm specimen of `rings` rings on an 18 cm support, as a tester sees it.
fn tester_with(rings: usize) -> (Model, DrapeTester) {
    let springs = SpringParams { stiffness: 1.0, damping: 0.0 };
    let mut model = Model::default();
    model.add_disk(&Disk {
        diameter: 0.30,
        rings,
        center: DVec3::new(0.01, 0.5, -0.02),
        orientation: Orientation::Horizontal,
        mass: 0.05,
        velocity: DVec3::ZERO,
        structural: springs,
        bending: springs,
        pins: Vec::new(),
    });
    let p = |i: u32| model.positions[i as usize];
    let specimen_area =
        model.triangles.iter().map(|&[a, b, c]| 0.5 * (p(b) - p(a)).cross(p(c) - p(a)).length()).sum();
    let tester = DrapeTester {
        triangles: 0..model.triangles.len(),
        specimen_area,
        support_center: [0.01, -0.02],
        support_radius: 0.09,
    };
    (model, tester)
}

/// A specimen that stays flat casts its own shadow: coefficient 1, within the raster's bound.
#[test]
fn a_flat_specimen_has_coefficient_one() {
    for rings in [3, 12, 30] {
        let (model, tester) = tester_with(rings);
        let d = drape_coefficient(&tester, &model.positions, &model.triangles).unwrap();
        assert!((d - 1.0).abs() <= RASTER_ERROR_BOUND, "{rings} rings: {d}");
    }
}

/// A specimen whose annulus hangs straight down from the support's edge casts no shadow beyond
/// the support: every particle outside radius r is moved onto the cylinder's side, straight
/// below where it left the edge, so its triangles project inside the support's disk:
/// coefficient 0.
#[test]
fn an_annulus_hanging_straight_down_has_coefficient_zero() {
    for rings in [6, 20] {
        let (mut model, tester) = tester_with(rings);
        let axis = DVec3::new(0.01, 0.5, -0.02);
        for p in &mut model.positions {
            let radial = *p - axis;
            let rho = radial.length();
            if rho > 0.09 {
                *p = axis + radial * (0.09 / rho) - DVec3::Y * (rho - 0.09);
            }
        }
        let d = drape_coefficient(&tester, &model.positions, &model.triangles).unwrap();
        assert!(d.abs() <= RASTER_ERROR_BOUND, "{rings} rings: {d}");
        // Not only by the disk: the raster sees the support's area itself.
        let points: Vec<[f64; 2]> = model.positions.iter().map(|p| [p.x, p.z]).collect();
        let support = Circle { center: [0.01, -0.02], radius: 0.09 };
        let disk_alone = shadow_area(&points, &[], Some(support), 1e-5).unwrap();
        assert!((disk_alone - PI * 0.09 * 0.09).abs() < 2.0 * PI * 0.09 * 1e-5);
    }
}

/// The hexagram, two overlapping equilateral triangles of side s, is non-convex and its union
/// has area `√3 s² / 3` (the big triangle and three of side s/3) and an outline of 12 edges of
/// s/3. The raster's error stays within `δ · 4s` at every row height, turned any way.
#[test]
fn measures_a_non_convex_union_within_its_bound() {
    let s = 0.2;
    let exact = 3f64.sqrt() * s * s / 3.0;
    let circumradius = s / 3f64.sqrt();
    for turn in [0.0, 0.1, 0.7, 1.3] {
        let points: Vec<[f64; 2]> = (0..6)
            .map(|k| {
                let angle = turn + TAU * k as f64 / 6.0;
                [0.3 + circumradius * angle.cos(), -0.1 + circumradius * angle.sin()]
            })
            .collect();
        let triangles = [[0, 2, 4], [1, 3, 5]];
        assert!(outline_bound(&points, &triangles) >= 4.0 * s);
        for row in [1e-2, 1e-3, 1e-4, 1e-5] {
            let area = shadow_area(&points, &triangles, None, row).unwrap();
            assert!((area - exact).abs() <= row * 4.0 * s, "turn {turn}, row {row}: {area} against {exact}");
        }
    }
}

/// The five-pointed star (outer radius R, inner radius r), fanned from its centre, has area
/// `5 R r sin 36°`; it is measured to within `δ · P`, P its perimeter of ten equal edges.
#[test]
fn measures_a_star_within_its_bound() {
    let (outer, inner) = (0.1, 0.04);
    let mut points = vec![[0.0, 0.0]];
    points.extend((0..10).map(|k| {
        let radius = if k % 2 == 0 { outer } else { inner };
        let angle = 0.3 + TAU * k as f64 / 10.0;
        [radius * angle.cos(), radius * angle.sin()]
    }));
    let triangles: Vec<[u32; 3]> = (0..10).map(|k| [0, 1 + k, 1 + (k + 1) % 10]).collect();
    let exact = 5.0 * outer * inner * (36f64).to_radians().sin();
    let edge = {
        let ([a, b], [c, d]) = (points[1], points[2]);
        (c - a).hypot(d - b)
    };
    assert!((outline_bound(&points, &triangles) - 10.0 * edge).abs() < 1e-15);
    let mut errors = Vec::new();
    for row in [4e-3, 1e-3, 2.5e-4] {
        let area = shadow_area(&points, &triangles, None, row).unwrap();
        assert!((area - exact).abs() <= row * 10.0 * edge, "row {row}: {area} against {exact}");
        errors.push((area - exact).abs());
    }
    // The bound is no formality: the coarsest rows do miss part of the points.
    assert!(errors[0] > 1e-7, "{errors:?}");
}

/// An edge whose two triangles lie on opposite sides is inside the union; a fold, with both on
/// one side, is on the outline.
#[test]
fn an_outline_runs_along_folds_not_across_flat_edges() {
    let flat = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
    let triangles = [[0, 1, 2], [1, 3, 2]];
    let diagonal = 2f64.sqrt();
    assert!((outline_bound(&flat, &triangles) - 4.0).abs() < 1e-15);
    let folded = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.2, 0.2]];
    let perimeter = 1.0 + 1.0 + diagonal + 2.0 * 0.8f64.hypot(0.2);
    assert!((outline_bound(&folded, &triangles) - perimeter).abs() < 1e-15);
}

/// A specimen whose annulus hangs as a cone at angle φ below the horizontal casts a shadow that
/// is its outer ring's regular polygon shrunk to radius `r + (R - r) cos φ`, so its coefficient
/// is `(poly(r + (R - r) cos φ) - π r²) / (poly(R) - π r²)`, `poly(ρ) = 3n ρ² sin(2π / 6n)` for
/// `n` rings: at two resolutions, each within the raster's bound of its exact value.
#[test]
fn a_conical_drape_has_the_coefficient_of_its_shrunk_outline() {
    let (big, small) = (0.15, 0.09);
    for rings in [10, 20] {
        let polygon = |rho: f64| 3.0 * rings as f64 * rho * rho * (TAU / (6 * rings) as f64).sin();
        for angle in [0.3f64, 0.8, 1.2] {
            let (mut model, tester) = tester_with(rings);
            let axis = DVec3::new(0.01, 0.5, -0.02);
            for p in &mut model.positions {
                let radial = *p - axis;
                let rho = radial.length();
                if rho > small {
                    let out = rho - small;
                    *p = axis + radial * ((small + out * angle.cos()) / rho) - DVec3::Y * (out * angle.sin());
                }
            }
            let exact = (polygon(small + (big - small) * angle.cos()) - PI * small * small)
                / (polygon(big) - PI * small * small);
            let d = drape_coefficient(&tester, &model.positions, &model.triangles).unwrap();
            assert!((d - exact).abs() <= RASTER_ERROR_BOUND, "{rings} rings at {angle}: {d} against {exact}");
        }
    }
}
