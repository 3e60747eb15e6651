//! The f64 side's root finder (the fixed-point core has its own, in `piezo_drive::model`).

/// Root of a decreasing function with f(lo) ≥ 0 ≥ f(hi): Illinois (regula falsi) with a bisection
/// guard, to a bracket of `rel_tol` of the interval.
pub fn falling_root(f: impl Fn(f64) -> f64, lo: f64, hi: f64, rel_tol: f64) -> f64 {
    let (f_lo, f_hi) = (f(lo), f(hi));
    falling_root_from(f, (lo, f_lo), (hi, f_hi), rel_tol)
}

/// [`falling_root`] with `f` at the bracket's ends already known (`(lo, f(lo))`, `(hi, f(hi))`):
/// a caller that tested the bracket does not pay for its two ends again.
pub fn falling_root_from(
    f: impl Fn(f64) -> f64,
    (lo, f_lo): (f64, f64),
    (hi, f_hi): (f64, f64),
    rel_tol: f64,
) -> f64 {
    let (mut a, mut b) = (lo, hi);
    let (mut fa, mut fb) = (f_lo, f_hi);
    if fa <= 0.0 {
        return a;
    }
    if fb >= 0.0 {
        return b;
    }
    let tol = rel_tol * (hi - lo).abs().max(1e-12);
    let ftol = 1e-13 * (fa - fb);
    let mut side = 0i8;
    for i in 0..100 {
        let mut m = (a * fb - b * fa) / (fb - fa);
        if !(m > a && m < b) || i % 8 == 7 {
            m = 0.5 * (a + b);
        }
        let fm = f(m);
        if fm.abs() <= ftol {
            return m;
        }
        if fm > 0.0 {
            a = m;
            fa = fm;
            if side == 1 {
                fb *= 0.5;
            }
            side = 1;
        } else {
            b = m;
            fb = fm;
            if side == -1 {
                fa *= 0.5;
            }
            side = -1;
        }
        if b - a < tol {
            break;
        }
    }
    (a * fb - b * fa) / (fb - fa)
}

/// The load at which a motor stops moving forward: bisection on `forward(load)` over
/// `[0, top_n]` to a bracket of `tol_n`; 0 when it does not move forward at no load.
pub fn stall_load_n(forward: impl Fn(f64) -> bool, top_n: f64, tol_n: f64) -> f64 {
    if !forward(0.0) {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0, top_n);
    while hi - lo > tol_n {
        let mid = 0.5 * (lo + hi);
        if forward(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}
