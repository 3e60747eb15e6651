//! Command-line checks shared by every subcommand: one validation per quantity, one wording
//! (`--flag must be in (lo, hi] unit, got value`), output paths checked before any work, and
//! progress shown only on a terminal.

use anyhow::{bail, Result};
use std::io::IsTerminal;
use std::path::Path;

/// Largest preload any subcommand accepts (N): the plant's contact searches stop at 60 N.
pub const MAX_PRELOAD_N: f64 = 60.0;
/// Largest constant load against a move (N), several times any stall force of the motor.
pub const MAX_LOAD_N: f64 = 20.0;
/// Largest target or index position (µm): the simulated travel.
pub const MAX_POSITION_UM: f64 = 50_000.0;
/// Largest slider mass (kg).
pub const MAX_SLIDER_MASS_KG: f64 = 1000.0;

/// Checks `lo < value <= hi` (or `lo <= value` with `lo_closed`), finite; the one wording.
pub fn in_range(flag: &str, value: f64, lo: f64, lo_closed: bool, hi: f64, unit: &str) -> Result<f64> {
    let above_lo = if lo_closed { value >= lo } else { value > lo };
    if !(value.is_finite() && above_lo && value <= hi) {
        let open = if lo_closed { '[' } else { '(' };
        let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
        bail!("{flag} must be in {open}{lo}, {hi}]{unit}, got {value}");
    }
    Ok(value)
}

/// Preload force F0 (N): (0, 60].
pub fn preload_n(flag: &str, value: f64) -> Result<f64> {
    in_range(flag, value, 0.0, false, MAX_PRELOAD_N, "N")
}

/// A constant load on the slider (N), either sense: [−20, 20].
pub fn load_n(flag: &str, value: f64) -> Result<f64> {
    in_range(flag, value, -MAX_LOAD_N, true, MAX_LOAD_N, "N")
}

/// Peak-to-peak drive voltage (V): (0, amplifier range].
pub fn voltage_v(flag: &str, value: f64, amplifier_range_v: f64) -> Result<f64> {
    in_range(flag, value, 0.0, false, amplifier_range_v, "V")
}

/// Drive frequency (Hz): (0, a tenth of the DAC rate].
pub fn frequency_hz(flag: &str, value: f64, dac_rate_hz: f64) -> Result<f64> {
    in_range(flag, value, 0.0, false, 0.1 * dac_rate_hz, "Hz")
}

/// Drive direction: +1 or −1.
pub fn direction(flag: &str, value: i64) -> Result<i8> {
    match value {
        1 => Ok(1),
        -1 => Ok(-1),
        _ => bail!("{flag} must be 1 or -1, got {value}"),
    }
}

/// Moving mass of the slider (kg): (0, 1000].
pub fn slider_mass_kg(flag: &str, value: f64) -> Result<f64> {
    in_range(flag, value, 0.0, false, MAX_SLIDER_MASS_KG, "kg")
}

/// A slider position (µm): [−50000, 50000].
pub fn position_um(flag: &str, value: f64) -> Result<f64> {
    in_range(flag, value, -MAX_POSITION_UM, true, MAX_POSITION_UM, "µm")
}

/// Every value of a comma-separated list through the same check; an empty list is refused.
pub fn each<T: Copy>(flag: &str, values: &[T], check: impl Fn(&str, T) -> Result<T>) -> Result<()> {
    if values.is_empty() {
        bail!("{flag} needs at least one value");
    }
    for &v in values {
        check(flag, v)?;
    }
    Ok(())
}

/// An output file that the command will write at the end: its directory must exist and the path
/// must not be a directory. Checked before any simulation, so a typo costs nothing.
pub fn output_file(flag: &str, path: &Path) -> Result<()> {
    if path.as_os_str().is_empty() {
        bail!("{flag} needs a file name, got an empty path");
    }
    if path.is_dir() {
        bail!("{flag} {}: is a directory, not a file", path.display());
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!("{flag} {}: directory {} does not exist", path.display(), dir.display());
    }
    if let Ok(meta) = std::fs::metadata(path) {
        if meta.permissions().readonly() {
            bail!("{flag} {}: file is read-only", path.display());
        }
    }
    // Whether it can be written at all (directory permissions, a read-only file system): open it
    // the way the writer will, without truncating an existing file, and remove it again if this
    // probe created it. Before any simulation, so a long run does not end in a late I/O error.
    let existed = path.exists();
    match std::fs::OpenOptions::new().append(true).create(true).open(path) {
        Ok(_) => {
            if !existed {
                let _ = std::fs::remove_file(path);
            }
        }
        Err(e) => bail!("{flag} {}: cannot write there: {e}", path.display()),
    }
    Ok(())
}

/// An output directory the command creates if needed: its parent must exist (or be creatable)
/// and it must not be a file. Created here, before any work.
pub fn output_dir(flag: &str, path: &Path) -> Result<()> {
    if path.exists() && !path.is_dir() {
        bail!("{flag} {}: is a file, not a directory", path.display());
    }
    std::fs::create_dir_all(path)
        .map_err(|e| anyhow::anyhow!("{flag} {}: cannot create the directory: {e}", path.display()))?;
    Ok(())
}

/// Progress lines and bars go to stderr only when it is a terminal: a redirected stderr gets
/// errors and nothing else.
pub fn show_progress() -> bool {
    std::io::stderr().is_terminal()
}

/// Rounds to a multiple of `step` (the resolution that means something), for JSON outputs.
pub fn round_to(value: f64, step: f64) -> f64 {
    if !value.is_finite() {
        return value;
    }
    let r = (value / step).round() * step;
    // Printing through the decimal shortest representation removes the binary residue
    // (0.1627000000001 → 0.1627).
    let digits = (-step.log10()).ceil().max(0.0) as usize;
    format!("{r:.digits$}").parse().unwrap_or(r)
}

/// serde helpers: round a field to its resolution when serialised.
pub mod ser {
    use serde::Serializer;

    fn opt<S: Serializer>(v: &Option<f64>, step: f64, s: S) -> Result<S::Ok, S::Error> {
        match v {
            Some(x) => s.serialize_some(&super::round_to(*x, step)),
            None => s.serialize_none(),
        }
    }

    /// Times to 1 ns.
    pub fn time_s<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(super::round_to(*v, 1e-9))
    }
    /// Optional times to 1 ns.
    pub fn opt_time_s<S: Serializer>(v: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        opt(v, 1e-9, s)
    }
    /// Positions in nm to 0.1 nm.
    pub fn nm<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(super::round_to(*v, 0.1))
    }
    /// Optional positions in nm to 0.1 nm.
    pub fn opt_nm<S: Serializer>(v: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        opt(v, 0.1, s)
    }
    /// Positions in µm to 0.1 nm.
    pub fn um<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(super::round_to(*v, 1e-4))
    }
    /// Forces in N to 1e-4 N.
    pub fn newton<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(super::round_to(*v, 1e-4))
    }
    /// Speeds in mm/s to 1 nm/s.
    pub fn mm_s<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(super::round_to(*v, 1e-6))
    }
    /// Angles in rad to 1 µrad.
    pub fn rad<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(super::round_to(*v, 1e-6))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_keeps_the_resolution_and_drops_the_residue() {
        assert_eq!(round_to(0.1627000000001627, 1e-9), 0.1627);
        assert_eq!(round_to(15.999999999999979, 1e-4), 16.0);
        assert_eq!(round_to(-19969.371732379543, 0.1), -19969.4);
        assert_eq!(round_to(0.00003718493071986089, 1e-4), 0.0);
        assert_eq!(round_to(1.23456789e-3, 1e-9), 0.001234568);
        assert!(round_to(f64::NAN, 0.1).is_nan());
    }

    #[test]
    fn one_wording_for_every_range() {
        let e = preload_n("--preload-n", -5.0).unwrap_err().to_string();
        assert_eq!(e, "--preload-n must be in (0, 60] N, got -5");
        let e = load_n("--load-n", 30.0).unwrap_err().to_string();
        assert_eq!(e, "--load-n must be in [-20, 20] N, got 30");
        assert_eq!(preload_n("--preload-n", 60.0).unwrap(), 60.0);
        assert!(preload_n("--preload-n", f64::NAN).is_err());
        assert!(direction("--direction", 0).is_err());
    }
}
