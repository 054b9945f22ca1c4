//! `hilrig recover`: a cut-off recording salvaged into a new, valid file.

use anyhow::{bail, Result};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct RecoverArgs {
    /// The cut-off file (e.g. drive.mcap.active).
    file: PathBuf,
    /// Output file (default: the input name without `.active`, or with `.recovered.mcap`).
    #[arg(short, long)]
    output: Option<PathBuf>,
}

pub fn run(args: RecoverArgs) -> Result<ExitCode> {
    let output = match &args.output {
        Some(o) => o.clone(),
        None => {
            let name = args.file.to_string_lossy();
            match name.strip_suffix(".active") {
                Some(stem) if !std::path::Path::new(stem).exists() => PathBuf::from(stem),
                _ => PathBuf::from(format!(
                    "{}.recovered.mcap",
                    name.trim_end_matches(".active")
                )),
            }
        }
    };
    if output == args.file {
        bail!("the output would overwrite the input; give -o");
    }
    let r =
        hilrig::bag::recover::recover(&args.file, &output, &hilrig::bag::BagOptions::default())?;
    let out = output.display();
    for (topic, n) in &r.counts {
        eprintln!("{out}: {topic}: {n} messages");
    }
    match &r.stopped_by {
        Some(why) => eprintln!(
            "{}: cut off; reading stopped at: {why}",
            args.file.display()
        ),
        None => eprintln!("{}: the file was complete", args.file.display()),
    }
    eprintln!("{out}: {} messages recovered", r.messages);
    Ok(ExitCode::SUCCESS)
}
