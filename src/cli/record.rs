//! `hilrig record`: live from the rig's sensors, or from captures and logs with `--from`.

use anyhow::{bail, Context, Result};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct RecordArgs {
    /// The rig file.
    #[arg(long)]
    rig: PathBuf,
    /// Capture files to record from instead of the live sensors.
    #[arg(long, num_args = 1..)]
    from: Vec<PathBuf>,
    /// Output MCAP file (written as OUT.active until finished); live recordings default to
    /// the rig's output_dir/RIG-YYYYMMDDTHHMMSSZ.mcap.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

pub fn run(args: RecordArgs) -> Result<ExitCode> {
    let rig = hilrig::rig::Rig::load(&args.rig)?;
    let text = std::fs::read_to_string(&args.rig)
        .with_context(|| format!("cannot read {}", args.rig.display()))?;
    if args.from.is_empty() {
        return live(&rig, &text, args.output);
    }
    let Some(output) = args.output else {
        bail!("record --from needs -o OUT.mcap");
    };
    let summary = hilrig::record::record_from(&rig, &text, &args.from, &output)?;
    let out = output.display();
    for (topic, n) in &summary.counts {
        eprintln!("{out}: {topic}: {n} messages");
    }
    for (name, m, r, pairs) in &summary.clocks {
        eprintln!(
            "{out}: clock {name}: offset {:.3} ms, drift {:.2} ppm, residual p50 {:.0} us, p95 {:.0} us, max {:.0} us ({pairs} pairs)",
            m.offset_ns * 1e-6,
            m.drift * 1e6,
            r.p50_ns * 1e-3,
            r.p95_ns * 1e-3,
            r.max_ns * 1e-3
        );
    }
    let lidar_recorded = summary
        .counts
        .get(hilrig::bag::topics::VELODYNE_PACKETS)
        .is_some_and(|&n| n > 0);
    // Losses are counted among the packets that came: with none, "0 lost" would read as a
    // clean lidar recording.
    if lidar_recorded {
        let outages = match summary.lidar_outages {
            0 => String::new(),
            n => format!(" (of them in {n} outages of more than 2 s)"),
        };
        eprintln!("{out}: lidar packets lost: {}{outages}", summary.lidar_lost);
        if summary.lidar_input_pauses > 0 {
            eprintln!(
                "note: {out}: {} pauses of more than 2 s between the inputs (captures of separate sessions): not counted lost",
                summary.lidar_input_pauses
            );
        }
        if summary.lidar_time_jumps > 0 {
            eprintln!(
                "note: {out}: the lidar's clock jumped {} times (backwards, or by more than 2 s while its packets kept coming): re-synchronised or reset",
                summary.lidar_time_jumps
            );
        }
    }
    for e in &summary.input_errors {
        eprintln!("error: {e} (everything before it was recorded)");
    }
    let rejects = &summary.lidar_rejects;
    let gnss_rejects = &summary.gnss_rejects;
    print_rejects(&out.to_string(), "lidar packets", rejects);
    print_rejects(&out.to_string(), "GNSS serial frames", gnss_rejects);
    let gnss_failed = print_undecoded(&out.to_string(), &summary.gnss_undecoded)
        | print_gnss_streams(&out.to_string(), &summary.gnss_streams);
    if summary.attitude_untimed > 0 {
        eprintln!(
            "note: {out}: {} attitude reports came before the GNSS stream showed its date and are not on /gnss/attitude (their raw messages are on /gnss/nmea and /gnss/ubx)",
            summary.attitude_untimed
        );
    }
    // The rig's GNSS port is where the live receiver is; a capture brings its own serial
    // interfaces, which are read whatever their names. Say so when they differ.
    if let Some(g) = &rig.gnss {
        let port_name = std::path::Path::new(&g.port).file_name();
        let matches = summary
            .serial_interfaces
            .iter()
            .any(|n| std::path::Path::new(n).file_name() == port_name);
        if !summary.serial_interfaces.is_empty() && !matches {
            let names: Vec<&str> = summary
                .serial_interfaces
                .iter()
                .map(String::as_str)
                .collect();
            eprintln!(
                "note: GNSS read from the capture's serial interface {}; the rig's gnss.port {} is the live port and is not used with --from",
                names.join(", "),
                g.port
            );
        }
    }
    // Records the capture's reader could not use: damaged ones may have been the rig's data.
    let skips = &summary.capture_records;
    for (reason, n) in &skips.damaged {
        eprintln!("error: {out}: {n} capture records not recorded: damaged ({reason})");
    }
    for (reason, n) in &skips.other {
        eprintln!("note: {out}: {n} capture records of other traffic ignored ({reason})");
    }
    let damaged = skips.damaged_total();
    if let Some(l) = rig
        .lidar
        .as_ref()
        .filter(|_| !lidar_recorded && damaged > 0)
    {
        let reasons: Vec<&str> = skips.damaged.keys().copied().collect();
        eprintln!(
            "error: no lidar data packets to port {} recorded; {damaged} capture records were damaged ({}): a capture cut by its snap length (tcpdump -s) loses every lidar packet",
            l.data_port,
            reasons.join(", ")
        );
    }
    // A rig with a lidar whose ports match nothing in the captures records no lidar at all:
    // say where the captures' UDP traffic went instead of reporting nothing lost.
    // (Inputs without any UDP traffic, such as CAN and GNSS logs, have no lidar to miss.)
    let no_lidar = rig
        .lidar
        .as_ref()
        .filter(|_| !summary.other_udp_ports.is_empty() && !lidar_recorded);
    if let Some(l) = no_lidar {
        let ports: Vec<String> = summary
            .other_udp_ports
            .iter()
            .map(|(p, n)| format!("{p} ({n} datagrams)"))
            .collect();
        eprintln!(
            "error: no lidar data packets to port {} in the input; its UDP traffic goes to port {}: set [lidar] data_port and position_port in the rig file to the capture's ports",
            l.data_port,
            ports.join(", ")
        );
    }
    Ok(
        if summary.input_errors.is_empty()
            && no_lidar.is_none()
            && rejects.is_empty()
            && gnss_rejects.is_empty()
            && !gnss_failed
            && damaged == 0
        {
            ExitCode::SUCCESS
        } else {
            ExitCode::from(1)
        },
    )
}

fn live(rig: &hilrig::rig::Rig, text: &str, output: Option<PathBuf>) -> Result<ExitCode> {
    let output = match output {
        Some(o) => o,
        None => hilrig::record::live::default_output(rig)?,
    };
    eprintln!("recording to {} (Ctrl-C to finish)", output.display());
    let summary = hilrig::record::live::record_until_signal(rig, text, &output)?;
    for (topic, n) in &summary.counts {
        eprintln!("{}: {topic}: {n} messages", output.display());
    }
    let rejects = &summary.lidar_rejects;
    let gnss_rejects = &summary.gnss_rejects;
    let out = output.display().to_string();
    print_rejects(&out, "lidar packets", rejects);
    print_rejects(&out, "GNSS serial frames", gnss_rejects);
    let gnss_failed = print_undecoded(&out, &summary.gnss_undecoded)
        | print_gnss_streams(&out, summary.gnss_stream.as_slice());
    // While the serial port was gone, its bytes were lost.
    let disconnects = summary.gnss_disconnects;
    if disconnects > 0 {
        eprintln!(
            "error: {out}: the GNSS serial port was lost {disconnects} times ({} reopened); what the receiver sent meanwhile is not recorded",
            summary.health.get("gnss").map_or(0, |v| v[5])
        );
    }
    Ok(
        if summary.dropped() == 0
            && rejects.is_empty()
            && gnss_rejects.is_empty()
            && !gnss_failed
            && disconnects == 0
        {
            ExitCode::SUCCESS
        } else {
            ExitCode::from(1)
        },
    )
}

/// Says what a recording left out, per reason with its first occurrence.
fn print_rejects<R: hilrig::record::rejects::Reason>(
    out: &str,
    what: &str,
    rejects: &hilrig::record::rejects::Rejects<R>,
) {
    if rejects.is_empty() {
        return;
    }
    eprintln!(
        "error: {out}: {} {what} were not recorded (counted in the file's hilrig/end metadata):",
        rejects.total()
    );
    for line in rejects.lines() {
        eprintln!("  {line}");
    }
}

/// Says which GNSS messages were recorded but did not decode; whether there were any (an
/// error: their fixes or attitude are missing).
fn print_undecoded(out: &str, undecoded: &hilrig::record::rejects::GnssUndecoded) -> bool {
    if !undecoded.is_empty() {
        eprintln!(
            "error: {out}: {} GNSS messages are recorded but did not decode, so their fixes or attitude are missing from /gnss/fix and /gnss/attitude (counted in the file's hilrig/end metadata):",
            undecoded.total()
        );
        for line in undecoded.lines() {
            eprintln!("  {line}");
        }
    }
    !undecoded.is_empty()
}

/// Says, per GNSS serial stream, what did not become a frame or a fix; whether one stream
/// failed: none of its bytes framed (another protocol, a wrong baud rate: its bytes are
/// recorded raw, but no fix comes of them), or it gave positions but never a date (none of
/// its fixes is on /gnss/fix).
fn print_gnss_streams(out: &str, streams: &[hilrig::record::gnss_stream::GnssStream]) -> bool {
    let mut failed = false;
    for s in streams {
        let name = &s.name;
        if s.unframed() {
            eprintln!(
                "error: {out}: GNSS stream {name}: its {} bytes hold no NMEA, UBX or RTCM3 frame ({} gpsd comment lines): recorded raw on /gnss/unframed, but no fix comes of them: another protocol, or the wrong baud rate?",
                s.unframed_bytes, s.comment_lines
            );
            failed = true;
        } else if s.unframed_bytes > 0 {
            eprintln!(
                "note: {out}: GNSS stream {name}: {} bytes were in no frame (frames cut off at the stream's start or end, rejected frames, bytes between frames), recorded as they came on /gnss/unframed",
                s.unframed_bytes
            );
        }
        if s.dateless() {
            eprintln!(
                "error: {out}: GNSS stream {name}: none of its {} fixes could be written to /gnss/fix: it never gave a date (no RMC, ZDA or UBX time); its messages are on /gnss/nmea and /gnss/ubx",
                s.fixes_untimed
            );
            failed = true;
        } else if s.fixes_untimed > 0 {
            eprintln!(
                "note: {out}: GNSS stream {name}: {} fixes came before it showed its date and are not on /gnss/fix (their messages are on /gnss/nmea and /gnss/ubx)",
                s.fixes_untimed
            );
        }
    }
    failed
}
