//! `host-sim`: the motor on your desk. See `host-sim --help`.

mod cli;

use anyhow::{bail, Result};
use clap::Parser;
use cli::gap::GapArgs;
use cli::pil::PilArgs;
use cli::{Cli, Command, FrictionArg, PointArgs, TableModelArg};
use host_sim::harness::contact_table::TableModel;
use host_sim::harness::moves;
use host_sim::motor::params::Params;
use host_sim::motor::steady::{OperatingPoint, ThrustModel};
use host_sim::motor::steady_inertia::InertialModel;
use host_sim::{check, curve, paper, plot};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// clap's error on one line: its message and tips without the usage block, and a pointer to the
/// help of the subcommand the user was typing (`host-sim move --help`), not the top level.
fn one_line_clap_error(e: &clap::Error, args: &[String]) -> String {
    use clap::CommandFactory;
    let text = e.to_string();
    let mut parts: Vec<&str> = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.starts_with("Usage:") || line.starts_with("For more information") {
            break;
        }
        if !line.is_empty() {
            parts.push(line);
        }
    }
    let mut message = parts.join(" ");
    if message.is_empty() {
        message = "error: invalid arguments".into();
    }
    let cmd = Cli::command();
    let sub = args.iter().skip(1).find_map(|a| {
        cmd.get_subcommands().find(|s| s.get_name() == a.as_str()).map(|s| s.get_name().to_string())
    });
    match sub {
        Some(name) => format!("{message} (see host-sim {name} --help)"),
        None => format!("{message} (see host-sim --help)"),
    }
}
fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
                let _ = e.print();
                return ExitCode::SUCCESS;
            }
            if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                let _ = e.print();
                return ExitCode::from(2);
            }
            let args: Vec<String> = std::env::args().collect();
            eprintln!("{}", one_line_clap_error(&e, &args));
            return ExitCode::from(2);
        }
    };
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // `{:#}` joins the context chain on one line.
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}

/// Progress of a points loop, on a terminal only.
fn progress(label: &str) -> impl FnMut(usize, usize) + '_ {
    let show = check::show_progress();
    move |done, total| {
        if !show {
            return;
        }
        let mut err = std::io::stderr();
        let _ = write!(err, "\r{label}: {done}/{total} points simulated");
        if done == total {
            let _ = writeln!(err);
        }
        let _ = err.flush();
    }
}

fn run(cli: Cli) -> Result<()> {
    let mut params = match &cli.params {
        Some(path) => Params::load(path)?,
        None => Params::prototype(),
    };
    if let Some(mass_kg) = cli.slider_mass_kg {
        params.slider.mass_kg = check::slider_mass_kg("--slider-mass-kg", mass_kg)?;
    }
    match cli.command {
        Command::Curve { point, points, friction, json, plot: plot_path } => {
            cmd_curve(params, point, points, friction, json, plot_path)
        }
        Command::ModelGrid { json } => cmd_model_grid(&params, json),
        Command::Paper { json, model_only } => cmd_paper(&params, json, model_only),
        Command::Move { to_um, preload_n, load_n, no_feedforward, load_known, json, plot: plot_path } => {
            let spec = moves::MoveSpec { to_um, preload_n, load_n, feedforward: !no_feedforward, load_known };
            cmd_move(&params, spec, json, plot_path)
        }
        Command::Trace { point, load_n, masses_kg, json, plot: plot_path } => {
            cmd_trace(&params, point, load_n, masses_kg, json, plot_path)
        }
        Command::Pil(args) => cmd_pil(&params, args),
        Command::Gap(args) => cmd_gap(&params, args),
        Command::Measure(args) => host_sim::gap::measure::run(args.into(), &params),
        Command::Characterize(args) => host_sim::virtual_controller::characterize::run(&args.into()),
        Command::Calibrate(args) => host_sim::virtual_controller::calibrate::run(&params, &args.into()),
        Command::Moves(args) => host_sim::virtual_controller::gcs_moves::run(&args.into()),
        Command::Sweep { json, preload_n, model } => cmd_sweep(&params, json, preload_n, model),
        Command::Demo { plot: plot_path } => cmd_demo(&params, plot_path),
        Command::Serve(args) => host_sim::virtual_controller::serve::run(&params, &args.into()),
        Command::ReadmeFigures(args) => host_sim::readme_figures::run(&args.into()),
        Command::FirmwareTable => cmd_firmware_table(&params, cli.params.as_deref()),
    }
}

/// `host-sim curve`: the thrust–velocity characteristic, model and plant side by side.
fn cmd_curve(
    mut params: Params,
    point: PointArgs,
    points: usize,
    friction: Option<FrictionArg>,
    json: bool,
    plot_path: Option<PathBuf>,
) -> Result<()> {
    let op = point.validate(&params)?;
    if !(2..=200).contains(&points) {
        bail!("--points must be in [2, 200], got {points}");
    }
    if let Some(path) = &plot_path {
        check::output_file("--plot", path)?;
    }
    if let Some(model) = friction {
        params.friction.model = model.into();
    }
    let c = curve::compute(&params, op, point.direction, points, 0.9, progress("curve"));
    if let Some(path) = &plot_path {
        plot::thrust_velocity(&c, path)?;
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&c)?);
    } else {
        print_curve(&c);
        if let Some(path) = &plot_path {
            println!("plot written to {}", path.display());
        }
    }
    Ok(())
}

/// `host-sim model-grid`: each steady-state model's worst error against the plant, per carriage.
fn cmd_model_grid(params: &Params, json: bool) -> Result<()> {
    let grid = host_sim::model_grid::compute(params);
    if json {
        println!("{}", serde_json::to_string_pretty(&grid)?);
    } else {
        println!("worst error in % of the plant's no-load speed, per carriage:");
        println!(
            "{:>9} {:>15} {:>15} {:>15} {:>15}",
            "carriage", "constant-speed", "inertia", "contact", "firmware"
        );
        for (m, c, i, k, fw) in host_sim::model_grid::worst_per_mass(&grid) {
            println!("{:>6} kg {c:>14.1}% {i:>14.1}% {k:>14.1}% {fw:>14.1}%", m);
        }
    }
    Ok(())
}

/// `host-sim paper`: the paper's figures against ours.
fn cmd_paper(params: &Params, json: bool, model_only: bool) -> Result<()> {
    let evaluate = if model_only { paper::Evaluate::ModelOnly } else { paper::Evaluate::ModelAndPlant };
    let show = check::show_progress();
    let rows = paper::rows(params, evaluate, |what| {
        if show {
            eprintln!("paper: {what}...");
        }
    });
    if json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        println!(
            "slider {} kg, counterweight {} kg, foot {} kg",
            params.slider.mass_kg, params.stator.counterweight_mass_kg, params.stator.foot_mass_kg
        );
        println!(
            "{:<30} {:<34} {:>10} {:>10} {:<6} {:<34} model / plant",
            "figure", "paper", "model", "plant", "unit", "we hold"
        );
        let verdict = |pass: bool| if pass { "pass" } else { "FAIL" };
        for r in &rows {
            println!(
                "{:<30} {:<34} {:>10.3} {:>10} {:<6} {:<34} {} / {}",
                r.name,
                r.paper,
                r.ours,
                r.plant.map_or("-".into(), |v| format!("{v:.3}")),
                r.unit,
                r.tolerance,
                verdict(r.pass),
                r.plant_pass.map_or("-", verdict),
            );
        }
        let failed = rows.iter().filter(|r| !r.pass).count();
        let plant_rows = rows.iter().filter(|r| r.plant_pass.is_some()).count();
        let plant_failed = rows.iter().filter(|r| r.plant_pass == Some(false)).count();
        println!("model: {} of {} rows pass", rows.len() - failed, rows.len());
        if plant_rows > 0 {
            println!("plant: {} of {} rows pass", plant_rows - plant_failed, plant_rows);
        }
    }
    Ok(())
}

/// `host-sim move`: one closed-loop move from 0.
fn cmd_move(params: &Params, spec: moves::MoveSpec, json: bool, plot_path: Option<PathBuf>) -> Result<()> {
    let moves::MoveSpec { to_um, preload_n, load_n, .. } = spec;
    check::position_um("--to-um", to_um)?;
    check::preload_n("--preload-n", preload_n)?;
    check::load_n("--load-n", load_n)?;
    if let Some(path) = &plot_path {
        check::output_file("--plot", path)?;
    }
    if check::show_progress() {
        eprintln!("simulating the move (controller at 10 kHz against the plant at 1 MHz)...");
    }
    let r = moves::single_move(params, spec)?;
    if let Some(path) = &plot_path {
        plot::motion(&r.trace, &format!("move to {to_um} µm, F0 {preload_n} N, load {load_n} N"), path)?;
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!("move 0 → {to_um} µm at F0 {preload_n} N against {load_n} N");
        match &r.fault {
            Some(f) => {
                println!("fault/refusal: {} (code {})", f.text, f.code);
                if let Some(back) = r.slide_back_nm {
                    println!(
                        "before the fault: overshoot {:.1} nm past the target, then slid back {:.1} nm \
                         against the move, ending {:.1} nm from the target",
                        r.overshoot_nm, back, r.final_error_nm
                    );
                }
            }
            None => println!(
                "settle time {}, final error {:.1} nm, overshoot {:.1} nm, max following error {:.3} µm, \
                 drive frequency {:.0} Hz",
                r.settle_time_s.map_or("never".into(), |t| format!("{t:.4} s")),
                r.final_error_nm,
                r.overshoot_nm,
                r.max_following_error_um,
                r.drive_frequency_hz
            ),
        }
    }
    Ok(())
}

/// `host-sim trace`: one settled drive period of the plant, per slider mass.
fn cmd_trace(
    params: &Params,
    point: PointArgs,
    load_n: f64,
    masses_kg: Vec<f64>,
    json: bool,
    plot_path: Option<PathBuf>,
) -> Result<()> {
    let op = point.validate(params)?;
    if point.direction != 1 {
        bail!(
            "--direction: trace runs the +1 direction only (the other is its mirror), got {}",
            point.direction
        );
    }
    check::load_n("--load-n", load_n)?;
    if !masses_kg.is_empty() {
        // The same quantity as the global override, so the same check and wording.
        check::each("--masses-kg (slider masses, as --slider-mass-kg)", &masses_kg, check::slider_mass_kg)?;
    }
    if let Some(path) = &plot_path {
        check::output_file("--plot", path)?;
    }
    let masses = if masses_kg.is_empty() { vec![params.slider.mass_kg] } else { masses_kg };
    let mut traces = Vec::new();
    for m in masses {
        let mut p = params.clone();
        p.slider.mass_kg = m;
        traces.push(host_sim::trace::one_period(&p, op, load_n, 720));
    }
    if let Some(path) = &plot_path {
        plot::period(&traces, path)?;
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&traces)?);
    } else {
        println!(
            "F0 {} N, {} V p-p, {} Hz, load {} N: one settled drive period",
            op.preload_n, op.voltage_v, op.frequency_hz, load_n
        );
        if let Some(t) = traces.first() {
            println!(
                "contact {:.1} % of the period, centred at {:.0}°; the foot's peak forward speed is at {:.0}°",
                100.0 * t.contact_fraction,
                t.contact_centre_deg,
                t.foot_peak_speed_deg
            );
        }
        println!(
            "{:>10} {:>14} {:>16} {:>18}",
            "slider kg", "speed mm/s", "advance µm/per", "stick % of contact"
        );
        for t in &traces {
            println!(
                "{:>10} {:>14.4} {:>16.4} {:>18.1}",
                t.slider_mass_kg,
                t.mean_speed_mm_s,
                t.advance_per_period_um,
                100.0 * t.stick_fraction_of_contact
            );
        }
        if let Some(path) = &plot_path {
            println!("plot written to {}", path.display());
        }
    }
    Ok(())
}

/// `host-sim pil`: the move with the core on the emulated Cortex-M4F, and its tick budget.
fn cmd_pil(params: &Params, args: PilArgs) -> Result<()> {
    if args.gcs_locks {
        return cmd_pil_locks(params, &args);
    }
    if args.lock_budget.is_some() {
        bail!("--lock-budget goes with --gcs-locks (the move's tick budget is --budget)");
    }
    let options = args.options();
    host_sim::harness::pil::validate(&options)?;
    let elf = match &args.elf {
        Some(path) => path.clone(),
        None => host_sim::harness::pil::build_target(&mut |what| eprintln!("pil: {what}..."))?,
    };
    eprintln!("pil: running the move with the core on the emulated Cortex-M4F...");
    let r = host_sim::harness::pil::run(params, &options, &elf)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!(
            "PIL move 0 → {} µm at F0 {} N against {} N: {} periods on the emulated M4",
            r.to_um, r.preload_n, r.load_n, r.ticks
        );
        match &r.fault {
            Some(f) => println!(
                "fault: {} (code {}); outputs safe after {} period(s)",
                f.text,
                f.code,
                r.fault_safe_after_ticks.map_or("no".into(), |n| n.to_string())
            ),
            None => println!(
                "settle time {}, final error {:.1} nm, overshoot {:.1} nm",
                r.settle_time_s.map_or("never".into(), |t| format!("{t:.4} s")),
                r.final_error_nm,
                r.overshoot_nm
            ),
        }
        println!(
            "tick (step + refill): mean {:.0}, max {} instructions; step alone: mean {:.0}, max {}",
            r.tick_instructions_mean,
            r.tick_instructions_max,
            r.step_instructions_mean,
            r.step_instructions_max
        );
        println!(
            "model table (thread-mode task on the board, not the tick): built {} times, max {} instructions; \
             in use: {} (last build {} instructions, {:.2} s at 170 MHz and one cycle each)",
            r.background_runs,
            r.background_instructions_max,
            r.table_model.unwrap_or("none"),
            r.table_build_instructions,
            f64::from(r.table_build_instructions) / 170e6
        );
        for (state, s) in &r.per_state {
            println!(
                "  {state:<12} {:>6} ticks, mean {:>6.0}, max {:>6} instructions",
                s.ticks, s.tick_instructions_mean, s.tick_instructions_max
            );
        }
        println!("periods whose outputs differ from the host build: {}", r.sil_mismatch_ticks);
    }
    if let Some(b) = &args.budget {
        let (mean, max) = (b.first().copied().unwrap_or(0), b.get(1).copied().unwrap_or(0));
        if r.tick_instructions_mean > f64::from(mean) || r.tick_instructions_max > max {
            bail!(
                "tick over budget: mean {:.0} (budget {mean}), max {} (budget {max}) instructions",
                r.tick_instructions_mean,
                r.tick_instructions_max
            );
        }
    }
    Ok(())
}

/// `host-sim pil --gcs-locks`: every GCS command's locked sections on the emulated M4, against
/// the lock budget.
fn cmd_pil_locks(params: &Params, args: &PilArgs) -> Result<()> {
    use host_sim::harness::pil_locks;
    let lock_budget = args.lock_budget.unwrap_or(pil_locks::DEFAULT_LOCK_BUDGET);
    let elf = match &args.elf {
        Some(path) => path.clone(),
        None => host_sim::harness::pil::build_target(&mut |what| eprintln!("pil: {what}..."))?,
    };
    eprintln!("pil: every GCS command through the core on the emulated Cortex-M4F...");
    let r = pil_locks::run(params, &elf)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!(
            "GCS commands on the emulated M4: instructions with the controller locked (the tick held off)"
        );
        println!(
            "{:<8} {:<34} {:>7}  {:<32} {:>9} {:>5}",
            "command", "sent", "locked", "locked sections", "whole", "error"
        );
        for l in &r.locks {
            let sections: Vec<String> =
                l.sections.iter().map(|s| format!("{} {}", s.what, s.instructions)).collect();
            println!(
                "{:<8} {:<34} {:>7}  {:<32} {:>9} {:>5}",
                l.command,
                l.line,
                l.instructions,
                sections.join(" + "),
                l.total_instructions,
                l.error
            );
        }
        println!(
            "longest locked section: {} instructions ({}); budget {}",
            r.max_lock_instructions, r.max_lock_command, lock_budget
        );
        println!(
            "{} control periods, {} whose outputs differ from the host build",
            r.ticks, r.sil_mismatch_ticks
        );
    }
    let mut problems = Vec::new();
    if !r.unmeasured_commands.is_empty() {
        problems.push(format!("commands not measured: {}", r.unmeasured_commands.join(", ")));
    }
    problems.extend(r.mismatches.iter().cloned());
    if r.sil_mismatch_ticks > 0 {
        problems.push(format!("{} periods differ between the M4 and the host build", r.sil_mismatch_ticks));
    }
    let over: Vec<String> = r
        .locks
        .iter()
        .flat_map(|l| l.sections.iter().map(move |s| (l, s)))
        .filter(|(_, s)| s.instructions > lock_budget)
        .map(|(l, s)| format!("{} ({}: {})", l.line, s.what, s.instructions))
        .collect();
    if !over.is_empty() {
        problems.push(format!(
            "locked sections over the budget of {} instructions: {}",
            lock_budget,
            over.join(", ")
        ));
    }
    if !problems.is_empty() {
        bail!("{}", problems.join("; "));
    }
    Ok(())
}

/// `host-sim gap`: the gap workflow, and a warning when the carriage is off its base model.
fn cmd_gap(params: &Params, args: GapArgs) -> Result<()> {
    host_sim::gap::run(args.into(), params)?;
    // A file whose base is the constant-speed model (eq. 19): say so (after the run, so that
    // an input error stays one line) when its carriage is light enough for its inertia to move
    // the speeds. The contact model (`[model] steady = "contact"`) has the carriage.
    if host_sim::gap::base::wants_contact(params) {
        return Ok(());
    }
    let op = OperatingPoint { preload_n: 16.0, voltage_v: 100.0, frequency_hz: 1500.0 };
    let constant = ThrustModel::new(params, op).no_load_speed_m_s();
    let inertial = InertialModel::new(params, op).no_load_speed_m_s();
    let off = (inertial - constant).abs() / constant.max(1e-12);
    if off > 0.05 {
        eprintln!(
            "warning: the {} kg carriage of this parameter file runs {:.0} % off the constant-speed model the gap workflow fits (16 N, 100 V, 1.5 kHz); the residuals include its inertia (the slider_inertia effect names it down to about 3 kg). Set `[model] steady = \"contact\"` in the file for the model with the carriage, or use a heavy characterisation sled (--params host-sim/params/heavy-slider.toml)",
            params.slider.mass_kg,
            100.0 * off
        );
    }
    Ok(())
}

/// `host-sim sweep`: the move sweep over slider masses and loads.
fn cmd_sweep(params: &Params, json: bool, preload_n: f64, model: TableModelArg) -> Result<()> {
    anyhow::ensure!(
        preload_n.is_finite() && preload_n > 0.0,
        "--preload-n must be a positive number of newtons, got {preload_n}"
    );
    let show = check::show_progress();
    let table_model = match model {
        TableModelArg::Core => TableModel::Core,
        TableModelArg::Contact => TableModel::Contact(Box::new(params.clone())),
        TableModelArg::CoreContact => TableModel::CoreContact,
    };
    let rows = host_sim::harness::sweep::run(params, preload_n, &table_model, |done, total| {
        if show {
            eprint!("\rsweep: {done}/{total} moves");
        }
    })?;
    if show {
        eprintln!();
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        println!(
            "{:>9}  {:<26} {:>6} {:>9} {:>8} {:>13} {:>9} {:>6}  fault",
            "slider kg", "move", "load N", "settle s", "× limit", "overshoot nm", "max FE µm", "f Hz"
        );
        for r in &rows {
            println!(
                "{:>9}  {:<26} {:>6.2} {:>9} {:>8} {:>13.1} {:>9.3} {:>6.0}  {}",
                r.slider_mass_kg,
                r.mv,
                r.load_n,
                r.settle_time_s.map_or("-".into(), |t| format!("{t:.4}")),
                r.limit_ratio.map_or("-".into(), |x| format!("{x:.2}")),
                r.overshoot_nm,
                r.max_following_error_um,
                r.drive_frequency_hz,
                r.fault.as_deref().unwrap_or("-")
            );
        }
    }
    Ok(())
}

/// `host-sim demo`: the closed-loop demo, its plot, and the curve at the paper's test point.
fn cmd_demo(params: &Params, plot_path: PathBuf) -> Result<()> {
    check::output_file("--plot", &plot_path)?;
    println!("Shaking-beam piezo motor, closed loop: the firmware's controller against the plant");
    let show = check::show_progress();
    let (rows, trace) = moves::demo(params, |label| {
        if show {
            eprintln!("demo: {label}...");
        }
    })?;
    println!(
        "{:<38} {:>12} {:>12} {:>14} {:>14} {:>12}  result",
        "step", "target µm", "settle s", "final err nm", "overshoot nm", "max FE µm"
    );
    for r in &rows {
        println!(
            "{:<38} {:>12.3} {:>12} {:>14} {:>14.1} {:>12.3}  {}",
            r.step,
            r.target_um,
            r.settle_time_s.map_or("-".into(), |t| format!("{t:.4}")),
            // A refused command has no final error.
            if r.final_error_nm.is_finite() { format!("{:.1}", r.final_error_nm) } else { "-".into() },
            r.overshoot_nm,
            r.max_following_error_um,
            r.result
        );
    }
    plot::demo(&trace, &rows, &plot_path)?;
    println!("plot written to {}", plot_path.display());
    let op = OperatingPoint { preload_n: 16.0, voltage_v: 100.0, frequency_hz: 1500.0 };
    println!("\nThrust–velocity characteristic at the paper's test point:");
    let c = curve::compute(params, op, 1, 6, 0.9, progress("curve"));
    print_curve(&c);
    Ok(())
}

/// `host-sim firmware-table`: the firmware's motor table, as Rust source.
fn cmd_firmware_table(params: &Params, params_path: Option<&Path>) -> Result<()> {
    let source = params_path
        .map_or_else(|| "host-sim/params/prototype.toml".to_string(), |path| path.display().to_string());
    print!("{}", host_sim::harness::sil::motor_table_source(params, &source));
    Ok(())
}

fn print_curve(c: &curve::Curve) {
    println!(
        "F0 {} N, {} V p-p, {} Hz, direction {:+}: contact force amplitude kc·Yc {:.2} N, contact angle {:.3} rad{}",
        c.preload_n,
        c.voltage_v,
        c.frequency_hz,
        c.direction,
        c.contact_force_amplitude_n,
        c.contact_angle_rad,
        if c.full_contact { " (full contact)" } else { "" }
    );
    println!(
        "stall force {:.3} N, no-load speed {:.3} mm/s, foot peak speed {:.3} mm/s",
        c.stall_force_n, c.no_load_speed_mm_s, c.foot_peak_speed_mm_s
    );
    println!(
        "with the {} kg slider's inertia: stall force {:.3} N, no-load speed {:.3} mm/s",
        c.slider_mass_kg, c.stall_force_inertia_n, c.no_load_speed_inertia_mm_s
    );
    println!(
        "{:>10} {:>16} {:>18} {:>18} {:>16} {:>9}",
        "load N", "model mm/s", "+inertia mm/s", "+contact mm/s", "plant mm/s", "diff %"
    );
    let plant_no_load = c.points.first().map_or(1.0, |p| p.speed_mm_s_sim.abs().max(1e-9));
    for p in &c.points {
        // The plant against the model with the contact's timing, in % of the plant's no-load speed.
        let diff = 100.0 * (p.speed_mm_s_sim - p.speed_mm_s_contact) / plant_no_load;
        println!(
            "{:>10.3} {:>16.4} {:>18.4} {:>18.4} {:>16.4} {:>9.2}",
            p.load_n, p.speed_mm_s_model, p.speed_mm_s_inertia, p.speed_mm_s_contact, p.speed_mm_s_sim, diff
        );
    }
    println!(
        "model: constant speed (eqs. 19–22); +inertia: with the carriage's inertia; +contact: with the \
         contact's timing too (steady_contact); diff %: plant minus +contact, in % of the plant's \
         no-load speed"
    );
}
