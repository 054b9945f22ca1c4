//! The `hilrig` command line: parses the arguments and hands each command to its module in
//! [`cli`], which validates them into typed settings, makes one call into the library and prints
//! the result. Nothing here does the work itself.

// Functions stay under about 150 lines here as in the library (clippy.toml); a longer one says
// why above it.
#![warn(clippy::too_many_lines)]

mod cli;

use clap::{Parser, Subcommand};
use std::io;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "hilrig",
    version,
    about = "Hardware-in-the-loop recorder and replay rig for validating lidar sensor models"
)]
struct Cli {
    /// More log output (-v info, -vv debug); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Decode a capture or log: lidar points (pcap/pcapng) or GNSS fixes (serial logs, gpsd logs,
    /// serial interfaces of pcapng captures).
    Decode(cli::decode::DecodeArgs),
    /// Record the rig's sensors live (or, with --from, captures: pcap/pcapng with lidar UDP,
    /// SocketCAN and serial interfaces) into one time-synchronised MCAP (ROS 2 profile).
    Record(cli::record::RecordArgs),
    /// Salvage an MCAP that was cut off (power loss, kill -9, full disk): every complete record
    /// before the cut goes into a new, valid file.
    Recover(cli::recover::RecoverArgs),
    /// Summarise an MCAP: channels, types, counts, rates, time span, clock synchronisation.
    Info(cli::info::InfoArgs),
    /// Play a recording (.mcap) or capture (.pcap/.pcapng) back to a device under test at the
    /// original pace: lidar over UDP, GNSS to a serial port or a new pty, CAN to an interface.
    Replay(cli::replay::ReplayArgs),
    /// Synthesize measured drives through a scene: per repetition a capture as it would come off
    /// the vehicle (lidar, GNSS serial, CAN) with realistic reference errors, the surveyed scene
    /// and the truth.
    Synth(cli::synth::SynthArgs),
    /// Check a recording's reference data (Rosenberger et al. 2019, §6): spatial and temporal accuracy, faults located
    /// in time, the smallest admissible grid cell. Exit 0 pass, 1 fail, 2 unusable input.
    Check(cli::check::CheckArgs),
    /// Re-simulate a recording: the same sensor on the same trajectory through the scene with a
    /// lidar model; writes simulated VelodyneScans and /sim/points. Refuses runs that fail
    /// `check` unless --force.
    Resim(cli::resim::ResimArgs),
    /// Compare a recording with its re-simulation scan by scan (Rosenberger et al. 2019, §5):
    /// OCR^K and other grid and point metrics at a cell the reference data admit, the
    /// calibration curve over cell sizes, and OCR against the distance to the objects (Fig. 5).
    /// Exit 2 when the two cannot be compared.
    Compare(cli::compare::CompareArgs),
    /// eFAST sensitivity (Rosenberger et al. 2019, §4; SALib's semantics): `sample` the
    /// parameter sets, `analyze` one output per set into first-order and total indices.
    Efast(cli::efast::EfastArgs),
    /// Scenario coverage (Rosenberger et al. 2019, §4): validation samples that share a cell of
    /// the parameter space with parameterization samples. Exit 1 when any does.
    Coverage(cli::coverage::CoverageArgs),
    /// Statistical validation over repetitions (Rosenberger et al. 2019, §8, Fig. 7): traffic
    /// lights and the area validation metric per phase and metric, and one verdict.
    Validate(cli::validate::ValidateArgs),
    /// The gap workflow: find where simulation and measurement disagree, name the missing
    /// effect of the catalogue, fit it, and keep it only if the validation runs improve.
    Gap(cli::gap::GapArgs),
    /// The whole method on the bundled parking-lot drives: record, check, re-simulate,
    /// compare, validate, close the gap, and the HTML report.
    Demo(cli::demo::DemoArgs),
    /// The validation report (one self-contained HTML file) from the JSON that check,
    /// compare, validate and gap write.
    Report(cli::report::ReportArgs),
    /// Many drives through the method: a campaign planned into commands on files, run here
    /// (resumable) or printed for another engine (`campaign plan --json`).
    Campaign(cli::campaign::CampaignArgs),
    /// A JSON output of check, compare, validate or gap as Parquet tables, with labels.
    Table(cli::table::TableArgs),
}

fn init_logging(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(io::stderr)
        .with_target(false)
        .init();
}

fn main() -> ExitCode {
    // A file-size limit (or a quota) must end in a write error the recorder can report and
    // stop on, not in SIGXFSZ killing it mid-chunk.
    // SAFETY: setting a signal to SIG_IGN at startup, before any thread exists, installs no
    // handler code and cannot race.
    let _ = unsafe {
        nix::sys::signal::signal(
            nix::sys::signal::Signal::SIGXFSZ,
            nix::sys::signal::SigHandler::SigIgn,
        )
    };
    let cli = Cli::parse();
    init_logging(cli.verbose);
    let result = match cli.command {
        Command::Decode(args) => cli::decode::run(args),
        Command::Record(args) => cli::record::run(args),
        Command::Recover(args) => cli::recover::run(args),
        Command::Info(args) => cli::info::run(args),
        Command::Replay(args) => cli::replay::run(args),
        Command::Synth(args) => cli::synth::run(args),
        Command::Check(args) => cli::check::run(args),
        Command::Resim(args) => cli::resim::run(args),
        Command::Compare(args) => cli::compare::run(args),
        Command::Efast(args) => cli::efast::run(args),
        Command::Coverage(args) => cli::coverage::run(args),
        Command::Validate(args) => cli::validate::run(args),
        Command::Gap(args) => cli::gap::run_cli(args),
        Command::Demo(args) => cli::demo::run(args),
        Command::Report(args) => cli::report::run(args),
        Command::Campaign(args) => cli::campaign::run(args),
        Command::Table(args) => cli::table::run(args),
    };
    match result {
        Ok(code) => code,
        // A closed pipe (`hilrig decode ... | head`) is the reader's choice, not an error.
        Err(e)
            if e.chain().any(|c| {
                c.downcast_ref::<io::Error>()
                    .is_some_and(|io| io.kind() == io::ErrorKind::BrokenPipe)
            }) =>
        {
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {}", cli::describe(&e));
            ExitCode::from(2)
        }
    }
}
