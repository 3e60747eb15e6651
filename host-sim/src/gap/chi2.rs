//! The χ² and F distributions' upper tails and quantiles, for the workflow's noise tests (no
//! statistics crate in the dependency tree; the regularized incomplete gamma and beta functions
//! are enough).

/// ln Γ(x) for x > 0 (Lanczos, g = 7, 9 terms; relative error ~1e-15).
fn ln_gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection.
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = G[0];
    let t = x + 7.5;
    for (i, g) in G.iter().enumerate().skip(1) {
        a += g / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularized upper incomplete gamma Q(a, x) = Γ(a, x)/Γ(a): series below a + 1, Lentz's
/// continued fraction above (Numerical Recipes §6.2).
fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let lead = a * x.ln() - x - ln_gamma(a);
    if x < a + 1.0 {
        let (mut sum, mut term, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (1.0 - sum * lead.exp()).clamp(0.0, 1.0)
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (lead.exp() * h).clamp(0.0, 1.0)
    }
}

/// P(χ²_dof > x): the probability that pure noise gives a statistic at least `x`.
pub fn upper_tail(x: f64, dof: usize) -> f64 {
    gamma_q(0.5 * dof.max(1) as f64, 0.5 * x)
}

/// The `1 − alpha` quantile of χ² with `dof` degrees of freedom: pure noise exceeds it with
/// probability `alpha`.
pub fn quantile_upper(alpha: f64, dof: usize) -> f64 {
    upper_quantile(alpha, (dof.max(1) as f64) + 10.0, |x| upper_tail(x, dof))
}

/// The `x` at which a falling upper tail equals `alpha` (bisection, after doubling `hi` until
/// the tail at it is below `alpha`).
fn upper_quantile(alpha: f64, mut hi: f64, tail: impl Fn(f64) -> f64) -> f64 {
    let alpha = alpha.clamp(1e-300, 1.0);
    let mut lo = 0.0;
    while tail(hi) > alpha && hi < 1e12 {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if tail(mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-12 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// Regularized incomplete beta I_x(a, b), by Lentz's continued fraction on the side where it
/// converges fast (Numerical Recipes §6.4).
fn beta_i(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let front = (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    let cf = |a: f64, b: f64, x: f64| {
        let tiny = 1e-300;
        let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
        let mut c = 1.0;
        let mut d = 1.0 - qab * x / qap;
        if d.abs() < tiny {
            d = tiny;
        }
        d = 1.0 / d;
        let mut h = d;
        for m in 1..1000 {
            let m = m as f64;
            let m2 = 2.0 * m;
            for aa in [
                m * (b - m) * x / ((qam + m2) * (a + m2)),
                -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2)),
            ] {
                d = 1.0 + aa * d;
                if d.abs() < tiny {
                    d = tiny;
                }
                c = 1.0 + aa / c;
                if c.abs() < tiny {
                    c = tiny;
                }
                d = 1.0 / d;
                h *= d * c;
            }
            if (d * c - 1.0).abs() < 1e-15 {
                break;
            }
        }
        h
    };
    if x < (a + 1.0) / (a + b + 2.0) {
        (front * cf(a, b, x) / a).clamp(0.0, 1.0)
    } else {
        (1.0 - front * cf(b, a, 1.0 - x) / b).clamp(0.0, 1.0)
    }
}

/// P(F(d1, d2) > x): a ratio of two independent χ²/dof, with `d1` and `d2` degrees of freedom.
pub fn f_upper_tail(x: f64, d1: usize, d2: usize) -> f64 {
    let (d1, d2) = (d1.max(1) as f64, d2.max(1) as f64);
    if x <= 0.0 {
        return 1.0;
    }
    beta_i(0.5 * d2, 0.5 * d1, d2 / (d2 + d1 * x))
}

/// The `1 − alpha` quantile of F(d1, d2). The workflow's structure test uses it when the noise
/// itself is estimated from `d2` pseudo-residuals: a χ²/dof over an estimated noise variance is
/// F-distributed, and a handful of pseudo-residuals (one measured curve of three loads gives one)
/// leave the noise uncertain enough that the χ² limit would call noise structure.
pub fn f_quantile_upper(alpha: f64, d1: usize, d2: usize) -> f64 {
    upper_quantile(alpha, 10.0, |x| f_upper_tail(x, d1, d2))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// F table values (Abramowitz & Stegun, Table 26.9) and the χ² limit for many noise samples.
    #[test]
    fn f_quantiles_match_the_tables() {
        for (alpha, d1, d2, table) in [
            (0.05, 1, 10, 4.965),
            (0.01, 5, 20, 4.103),
            (0.001, 2, 10, 14.905),
            (0.001, 1, 10, 21.04),
            (0.05, 4, 30, 2.690),
        ] {
            let q = f_quantile_upper(alpha, d1, d2);
            assert!((q - table).abs() < 2e-3 * table, "F({d1}, {d2}) 1−{alpha}: {q} vs {table}");
        }
        // F(k, ∞) = χ²(k)/k.
        let q = f_quantile_upper(0.001, 2, 100_000);
        assert!((q - quantile_upper(0.001, 2) / 2.0).abs() < 0.01, "{q}");
    }

    /// Table values (Abramowitz & Stegun, Table 26.8).
    #[test]
    fn quantiles_match_the_tables() {
        for (alpha, dof, table) in [
            (0.05, 1, 3.841),
            (0.01, 1, 6.635),
            (0.001, 1, 10.828),
            (0.001, 2, 13.816),
            (0.001, 3, 16.266),
            (0.001, 4, 18.467),
            (0.05, 10, 18.307),
            (0.001, 30, 59.703),
        ] {
            let q = quantile_upper(alpha, dof);
            assert!((q - table).abs() < 2e-3, "χ²({dof}) 1−{alpha}: {q} vs {table}");
        }
        // Two degrees of freedom have a closed form: P(χ² > x) = exp(−x/2).
        for x in [0.1, 1.0, 5.0, 30.0] {
            assert!((upper_tail(x, 2) - (-0.5 * x).exp()).abs() < 1e-13);
        }
    }
}
