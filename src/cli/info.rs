//! `hilrig info`: channels, counts, rates, time span and clock synchronisation of an MCAP.

use anyhow::Result;
use std::io::{self, Write};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct InfoArgs {
    /// The MCAP file.
    file: PathBuf,
    /// Also write the summary as JSON here (what `hilrig report` lists of a recording).
    #[arg(long)]
    json: Option<PathBuf>,
}

pub fn run(args: InfoArgs) -> Result<ExitCode> {
    let i = hilrig::bag::info::info(&args.file)?;
    if let Some(path) = &args.json {
        hilrig::output::write(path, &i)?;
    }
    let mut out = io::stdout().lock();
    writeln!(out, "file: {}", args.file.display())?;
    writeln!(out, "profile: {}", i.profile)?;
    let secs = i.span.map(|s| (s.last_ns - s.first_ns) as f64 * 1e-9);
    match i.span.map(|s| (s.first_ns, s.last_ns)) {
        Some((a, b)) => writeln!(
            out,
            "time: {} .. {} ({:.3} s)",
            hilrig::stamp::civil::iso8601_millis(hilrig::stamp::UtcNanos(a as i64)),
            hilrig::stamp::civil::iso8601_millis(hilrig::stamp::UtcNanos(b as i64)),
            secs.unwrap_or(0.0)
        )?,
        None => writeln!(out, "time: (no messages)")?,
    }
    writeln!(out, "chunks: {}", i.chunks)?;
    writeln!(out, "channels:")?;
    for c in &i.channels {
        let rate = secs
            .filter(|s| *s > 0.0)
            .map(|s| format!("{:9.2} Hz", c.count as f64 / s))
            .unwrap_or_default();
        writeln!(
            out,
            "  {:24} {:36} {:>9} msgs {rate}",
            c.topic, c.message_type, c.count
        )?;
    }
    for (name, m) in &i.metadata {
        let kv: Vec<String> = m.iter().map(|(k, v)| format!("{k}={v}")).collect();
        writeln!(out, "metadata {name}: {}", kv.join(", "))?;
    }
    for a in &i.attachments {
        writeln!(
            out,
            "attachment {} ({}, {} bytes)",
            a.name, a.media_type, a.bytes
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
