//! The heavy elastica of a cantilever, the exact answer the cantilever tests compare against.

/// The heavy elastica of a cantilever, `θ'' = -λ (1 - s) cos θ` on `s ∈ [0, 1]` with `θ(0) = 0`
/// and `θ'(1) = 0` (`θ` the slope below horizontal, `s` the arc length over the free length,
/// `λ = w l³ / B`), by shooting on `θ'(0)` with RK4: the tip chord's angle below horizontal, in
/// radians.
pub fn elastica_chord_angle(lambda: f64) -> f64 {
    let [x, y] = elastica_tip(lambda);
    y.atan2(x)
}

/// The same elastica's tip, `[x, y]` over the free length: how far out from the clamp and how
/// far below it the strip ends.
pub fn elastica_tip(lambda: f64) -> [f64; 2] {
    const STEPS: usize = 4000;
    // Integrates (θ, θ', x, y) from 0 to 1.
    let shoot = |slope: f64| {
        let rate = |s: f64, [theta, bend, _, _]: [f64; 4]| {
            [bend, -lambda * (1.0 - s) * theta.cos(), theta.cos(), theta.sin()]
        };
        let h = 1.0 / STEPS as f64;
        let mut y = [0.0, slope, 0.0, 0.0];
        for k in 0..STEPS {
            let s = k as f64 * h;
            let add = |a: [f64; 4], b: [f64; 4], f: f64| std::array::from_fn(|i| a[i] + f * b[i]);
            let k1 = rate(s, y);
            let k2 = rate(s + 0.5 * h, add(y, k1, 0.5 * h));
            let k3 = rate(s + 0.5 * h, add(y, k2, 0.5 * h));
            let k4 = rate(s + h, add(y, k3, h));
            y = std::array::from_fn(|i| y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
        }
        y
    };
    // θ'(1) falls as θ'(0) grows while θ stays within a right angle: bisect on it.
    let (mut low, mut high) = (0.0, lambda);
    for _ in 0..100 {
        let middle = 0.5 * (low + high);
        if shoot(middle)[1] > 0.0 { high = middle } else { low = middle }
    }
    let [_, _, x, y] = shoot(0.5 * (low + high));
    [x, y]
}
