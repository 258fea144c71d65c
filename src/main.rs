//! `greybox`: fit PMSM parameters to drive logs from the command line.
//!
//! ```text
//! greybox fit LOG... --pole-pairs N [--model spm|ipm] [--hold auto|dq|stator] [--solver auto|lm|gn|trust-region] [--json PATH]
//! greybox fit --each DIR_OR_GLOB --pole-pairs N [fit flags] [--summary PATH] [--trend PATH.svg]
//! greybox validate LOG... --params REPORT.json [--json PATH] [--compare-dir DIR]
//! greybox track LOG... --pole-pairs N (--l-s H | --params REPORT.json) [--json PATH] [--max-points M]
//! greybox simulate (--scenario exp1..exp6 | --config FILE.json) -o LOG.csv [--motor spm|ipm] [--seed N] [--set PATH=VALUE]
//! greybox completions bash|zsh|fish|elvish|powershell > FILE
//! ```
//! The library does the work; this file only maps flags to options and prints.

use clap::{CommandFactory, Parser, Subcommand};
use greybox::cli;
use greybox::cli::args::FitArgs;
use std::process::ExitCode;

// The command line's allocator keeps freed pages for the next large buffer: a fit allocates
// and frees several record-length arrays, which the system allocator returns to the
// kernel and faults in again each time.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser, Debug)]
#[command(
    name = "greybox",
    version,
    about = "Grey-box estimation of PMSM parameters (R_s, L_s or L_d/L_q, K_e) from drive logs",
    after_help = "Exit codes: 0 success; 1 error (nothing computed, no report written); 2 invalid command line (an \
option, its value or a LOG argument the error names; nothing computed, no report written); \
3 `fit` finished and wrote its report, but the result is not to be trusted (not converged, a parameter at a bound, \
non-finite statistics, a likely setup mistake: see \"warnings\" in the report; --allow-unconverged turns this into 0); \
4 `fit --each`: a log could not be read or fitted (reported, skipped; the summary and trend plot are written). \
With --each, 3 means that no log failed but a fit is untrusted."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Fit a PMSM model to one or more logs (jointly, shared parameters) by the prediction-error method.
    Fit(Box<FitArgs>),
    /// Compare a saved fit (`--params REPORT.json`) with logs it was not fitted on: fit %, residual statistics, and the measured and simulated outputs for plotting.
    Validate(Box<cli::validate::ValidateArgs>),
    /// Run the online MRAS observer (K_e, R_s; thesis 5.1) over each log: final estimates and their trajectory.
    Track(Box<cli::track::TrackArgs>),
    /// Simulate a closed-loop servo drive (thesis scenarios exp1-exp6 or a scenario file): a log `greybox fit` reads, with its truth JSON.
    Simulate(Box<cli::simulate::SimulateArgs>),
    /// Predict the standard errors and 95 % intervals of planned experiments before running them, rank them, search design knobs.
    Design(Box<cli::design::DesignArgs>),
    /// Fit the saturation model (with cross-saturation) to a measured flux map: coefficients with standard errors, residuals, inductances.
    Fluxmap(Box<cli::fluxmap::FluxMapArgs>),
    /// Fit the saturated IPM model (cross-saturation) to drive logs beside the linear IPM fit: coefficients, inductances at the operating points.
    Saturation(Box<cli::saturation::SaturationArgs>),
    /// Fit R_s, the inductances and the inverter's voltage error to locked-rotor logs (the firmware's power-up test); the injection length for R_s to ±1 %.
    Standstill(Box<cli::standstill::StandstillArgs>),
    /// Fit inertia, viscous and Coulomb friction, gravity and a constant load to the speed and angle of drive logs, driven by the fitted electrical model's torque; friction per log.
    Mechanics(Box<cli::mechanics::MechanicsArgs>),
    /// Print a shell completion script on stdout, e.g. `greybox completions bash > /etc/bash_completion.d/greybox`
    /// or `greybox completions zsh > ~/.zfunc/_greybox`.
    Completions {
        /// The shell.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    greybox::estimate::set_progress_observer(Box::new(cli::progress::Spinner::default()));
    // Interrupted (SIGINT, SIGTERM, SIGHUP): the temporaries of outputs not yet renamed are
    // removed, the old outputs stay; exit 130 as a shell reports an interrupt.
    let _ = ctrlc::set_handler(|| {
        greybox::data::interrupt_removing_temporaries(|n| {
            if n > 0 {
                eprintln!(
                    "error: interrupted; {n} unfinished output file(s) removed, the files there before unchanged"
                );
            } else {
                eprintln!("error: interrupted; no output file was unfinished");
            }
            std::process::exit(130)
        })
    });
    // The exit code: 0, or 3 for an untrusted fit, 4 for a failed log of a batch.
    let code = |trusted: bool| if trusted { 0 } else { 3 };
    let r: greybox::Result<u8> = match &cli.command {
        Command::Fit(a) => match &a.each {
            Some(pattern) => cli::batch::run_batch(a, pattern),
            None => cli::fit::run_fit(a).map(code),
        },
        Command::Validate(a) => cli::validate::run_validate(a).map(|()| 0),
        Command::Track(a) => cli::track::run_track(a).map(code),
        Command::Simulate(a) => cli::simulate::run_simulate(a).map(|()| 0),
        Command::Design(a) => cli::design::run_design(a).map(|()| 0),
        Command::Fluxmap(a) => cli::fluxmap::run_fluxmap(a).map(code),
        Command::Saturation(a) => cli::saturation::run_saturation(a).map(code),
        Command::Standstill(a) => cli::standstill::run_standstill(a).map(code),
        Command::Mechanics(a) => cli::mechanics::run_mechanics(a).map(code),
        Command::Completions { shell } => {
            // Into a buffer first: clap_complete panics when stdout is closed early (`| head`).
            let mut script = Vec::new();
            clap_complete::generate(*shell, &mut Cli::command(), "greybox", &mut script);
            cli::output::stdout(&String::from_utf8_lossy(&script)).map(|()| 0)
        }
    };
    // A signal arrived: its handler is ending the process with 130 and its message.
    while greybox::data::interrupted() {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    // Errors name the flags of the subcommand that ran, as the user typed them.
    let r = r.map_err(|e| {
        let command = Cli::command();
        let name = match &cli.command {
            Command::Fit(_) => "fit",
            Command::Validate(_) => "validate",
            Command::Track(_) => "track",
            Command::Simulate(_) => "simulate",
            Command::Design(_) => "design",
            Command::Fluxmap(_) => "fluxmap",
            Command::Saturation(_) => "saturation",
            Command::Standstill(_) => "standstill",
            Command::Mechanics(_) => "mechanics",
            Command::Completions { .. } => "completions",
        };
        match command.find_subcommand(name) {
            Some(sub) => cli::errors::in_cli_words(e, sub),
            None => e,
        }
    });
    match r {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(exit_code_of(&e))
        }
    }
}

/// The exit code of an error: 2 when it names a flag, a value or an argument of the command
/// line (an invalid option, pole-pair number, bound or start), 1 otherwise.
fn exit_code_of(e: &greybox::Error) -> u8 {
    use greybox::Error;
    match e {
        Error::InvalidOption { .. } | Error::InvalidBounds { .. } | Error::StartOutsideBounds { .. } => 2,
        Error::Domain(_) if e.domain::<greybox::pmsm::PmsmError>().is_some() => 2,
        _ => 1,
    }
}
