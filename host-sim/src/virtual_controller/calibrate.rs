//! `host-sim calibrate`: upload a fitted motor model (the model-gap workflow's
//! `params-fitted.toml`) to a board, or to `host-sim serve`, without a rebuild.
//!
//! The feedforward's motor table stays the one the firmware was built with; what the workflow
//! fits goes into the parameters that calibrate it (README, "Parameters"): the friction
//! coefficient μd, the stator's tangential scale λ and normal force ratio ρ (the table is scaled
//! by the ratios to its own), the guide friction of the `rail_friction` effect and, when the
//! workflow found it, the carriage's mass of the `slider_inertia` effect. They go in
//! one `SPA` line, so the controller checks them as a whole and takes all or none; then `SPA?`
//! reads them back. Effects the fixed-point model does not carry are listed as not uploaded.
//! With `--tune`, λ is chosen first by simulating the board on the fitted model ([`super::tune`]).

use crate::motor::params::Params;
use crate::virtual_controller::calibration::spa_line;
pub use crate::virtual_controller::calibration::{calibration_values, not_carried};
use crate::virtual_controller::gcs_client::GcsClient;
use crate::virtual_controller::tune::{tune_lambda, TuneReport};
use anyhow::{bail, Result};
use serde::Serialize;
use std::path::PathBuf;

/// Where to upload and what else to do.
#[derive(Debug, Clone)]
pub struct CalibrateOptions {
    /// The controller's GCS over TCP; one of this and `serial`.
    pub tcp: Option<String>,
    /// The controller's GCS over a serial port.
    pub serial: Option<PathBuf>,
    pub baud: u32,
    /// Store the uploaded values in the controller's flash (`WPA`) after the read-back.
    pub save: bool,
    /// Print one JSON object instead of the table.
    pub json: bool,
    /// Choose λ by simulating the board on the fitted model first ([`super::tune`]): the file
    /// the board's firmware was built for, and the board's preload (N).
    pub tune: Option<(PathBuf, f64)>,
}

/// One uploaded parameter.
#[derive(Debug, Clone, Serialize)]
pub struct Uploaded {
    /// GCS parameter id (`SPA 1 <id>`).
    pub id: u32,
    /// Its name in the parameter file.
    pub name: &'static str,
    pub sent: f32,
    pub read_back: f32,
}

/// What `calibrate` did.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrateReport {
    pub uploaded: Vec<Uploaded>,
    /// Effects in the file that the firmware's fixed-point model does not carry: not uploaded.
    pub not_uploaded: Vec<String>,
    /// Whether `WPA` stored them.
    pub saved: bool,
    /// What `--tune` found (λ uploaded instead of the fitted one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tuned: Option<TuneReport>,
}

/// Sends the calibration in one line, reads it back, optionally stores it.
pub fn upload(gcs: &mut GcsClient, p: &Params, save: bool) -> Result<CalibrateReport> {
    let values = calibration_values(p);
    let line = spa_line(&values);
    gcs.send(&line)?;
    match gcs.error()? {
        0 => {}
        17 => bail!(
            "the controller refused the calibration (GCS error 17, value out of range): nothing was \
             changed. μd must be in (0, 2], the guide friction ≥ 0, and λ and ρ within 4× of the \
             values the board's motor table was computed with; a motor that far off needs its own \
             table (`host-sim firmware-table`). Sent: {line}"
        ),
        e => bail!(
            "the controller refused the calibration with GCS error {e}: nothing was changed. Sent: {line}"
        ),
    }
    let query = values.iter().fold(String::from("SPA?"), |mut s, (id, _, _)| {
        s.push_str(&format!(" 1 0x{id:X}"));
        s
    });
    let reply = gcs.query(&query)?;
    let mut uploaded = Vec::new();
    for (id, name, sent) in values {
        let key = format!("1 0x{id:X}=");
        let read_back = reply
            .lines()
            .find_map(|l| l.trim().strip_prefix(key.as_str()))
            .and_then(|v| v.trim().parse::<f32>().ok());
        let Some(read_back) = read_back else {
            bail!("'{query}' answered '{}' without parameter 0x{id:X}", reply.trim());
        };
        // The controller prints each f32 so that it reads back exactly.
        if read_back != sent {
            bail!("parameter 0x{id:X} ({name}): sent {sent}, the controller reads back {read_back}");
        }
        uploaded.push(Uploaded { id, name, sent, read_back });
    }
    if save {
        gcs.command("WPA")?;
    }
    Ok(CalibrateReport { uploaded, not_uploaded: not_carried(p), saved: save, tuned: None })
}

pub fn run(p: &Params, args: &CalibrateOptions) -> Result<()> {
    // The link is checked before the tuning's minute of simulation and opened again after it.
    drop(GcsClient::open(args.tcp.as_deref(), args.serial.as_deref(), args.baud)?);
    let (p, tuned) = match &args.tune {
        Some((firmware, preload_n)) => {
            let progress = |done: usize, total: usize| {
                if !args.json {
                    eprint!("\rtuning λ on the fitted model: {done}/{total} simulated board runs");
                }
            };
            let t = tune_lambda(p, firmware, *preload_n, &progress)?;
            if !args.json {
                eprintln!();
            }
            let mut q = p.clone();
            q.stator.tangential_scale = t.chosen_lambda;
            (q, Some(t))
        }
        None => (p.clone(), None),
    };
    let mut gcs = GcsClient::open(args.tcp.as_deref(), args.serial.as_deref(), args.baud)?;
    let mut report = upload(&mut gcs, &p, args.save)?;
    report.tuned = tuned;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
        return Ok(());
    }
    if let Some(t) = &report.tuned {
        println!(
            "λ tuned on the fitted model at {} N: mean peak following error of the simulated board's \
             moves out (0.5, 1, 2 mm; nm)",
            t.preload_n
        );
        println!("{:>10} {:>10} {:>14} {:>8}", "λ", "mean", "with next", "± se");
        for g in &t.grid {
            let mark = if g.lambda == t.chosen_lambda {
                "  <- uploaded"
            } else if g.lambda == t.fitted_lambda {
                "  (fitted)"
            } else {
                ""
            };
            println!(
                "{:>10.5} {:>10.0} {:>14.0} {:>8.0}{mark}",
                g.lambda, g.mean_peak_nm, g.neighbourhood_nm, g.neighbourhood_se_nm
            );
        }
        if t.kept_fitted {
            println!(
                "no λ beat the fitted one by more than two standard errors of the moves' spread: \
                 the fitted λ goes up"
            );
        }
    }
    println!("{:<8} {:<40} {:>14} {:>14}", "id", "parameter", "sent", "read back");
    for u in &report.uploaded {
        println!("{:<8} {:<40} {:>14} {:>14}", format!("0x{:X}", u.id), u.name, u.sent, u.read_back);
    }
    for name in &report.not_uploaded {
        println!(
            "not uploaded: {name} (the firmware's fixed-point model does not carry it; only the \
             simulator's model has it)"
        );
    }
    if report.saved {
        println!("stored in the controller's flash (WPA)");
    } else {
        println!("in effect until reset; `--save` (or WPA) stores it");
    }
    Ok(())
}
