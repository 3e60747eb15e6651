//! Plain feedback for the coarse mode without the thrust model (feedforward off): PI from position
//! error straight to signed drive volts, the integral held while the output is saturated the same
//! way (anti-windup).

use crate::fastmath::clamp_sym_f32;

/// The gains and the output bound.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PlainPiConfig {
    pub(super) kp_v_per_nm: f32,
    pub(super) ki_v_per_nm_s: f32,
    /// Largest drive (V peak-to-peak): the output's and the integral's bound.
    pub(super) max_v: f32,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PlainPi {
    cfg: PlainPiConfig,
    /// Integral term (V, signed along +x).
    integral_v: f32,
}

impl PlainPi {
    pub(super) fn new(cfg: PlainPiConfig) -> Self {
        PlainPi { cfg, integral_v: 0.0 }
    }

    pub(super) fn configure(&mut self, cfg: PlainPiConfig) {
        self.cfg = cfg;
    }

    /// One period: the signed drive (V along +x, not yet bounded: the caller takes its size
    /// within the largest drive and its sign as the direction).
    pub(super) fn update(&mut self, err_nm: f32, dt_s: f32) -> f32 {
        let max_v = self.cfg.max_v;
        let p_term = self.cfg.kp_v_per_nm * err_nm;
        let unclamped = p_term + self.integral_v;
        let pushing_limit = unclamped.abs() >= max_v && unclamped * err_nm > 0.0;
        if !pushing_limit {
            self.integral_v = clamp_sym_f32(self.integral_v + self.cfg.ki_v_per_nm_s * err_nm * dt_s, max_v);
        }
        p_term + self.integral_v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pi() -> PlainPi {
        PlainPi::new(PlainPiConfig { kp_v_per_nm: 0.01, ki_v_per_nm_s: 100.0, max_v: 10.0 })
    }

    #[test]
    fn proportional_plus_integral() {
        // 100 nm: P = 0.01 · 100 = 1 V; I grows 100 V/(nm·s) · 100 nm · 1e-4 s = 1 V a period.
        let mut c = pi();
        let u = c.update(100.0, 1e-4);
        assert!((u - 2.0).abs() < 1e-5, "{u}");
        let u = c.update(100.0, 1e-4);
        assert!((u - 3.0).abs() < 1e-5, "{u}");
    }

    #[test]
    fn integral_holds_while_saturated_the_same_way() {
        let mut c = pi();
        // P alone 20 V > 10 V pushing the limit: the integral stays at 0.
        assert_eq!(c.update(2000.0, 1e-4), 20.0);
        assert_eq!(c.integral_v, 0.0);
        // The other way the integral unwinds (−1 V per period here).
        c.integral_v = 5.0;
        let u = c.update(-100.0, 1e-4);
        assert!((c.integral_v - 4.0).abs() < 1e-5);
        assert!((u - 3.0).abs() < 1e-5, "{u}");
    }

    #[test]
    fn integral_is_bounded_by_the_largest_drive() {
        let mut c = PlainPi::new(PlainPiConfig { kp_v_per_nm: 0.0, ki_v_per_nm_s: 1e6, max_v: 10.0 });
        assert_eq!(c.update(1000.0, 1e-4), 10.0);
        assert_eq!(c.update(-1e5, 1e-4), -10.0);
    }
}
