//! The reference streams as the vehicle sends them, for `synth`: the GNSS receiver's serial
//! NMEA (GGA, RMC, GST) with Gauss-Markov RTK noise, latency and jitter, and the ego CAN frames
//! through the rig's DBC mapping, each with the injected faults of the drive file. Each stream
//! draws from its own random stream, so adding one never changes another.

use super::drive::{CanStream, Driven, Faults, GnssStream, HeadingStream};
use crate::rig::{CanConfig, GnssConfig};
use crate::scene::file::Wgs84;
use crate::scene::geodesy::Enu;
use hilrig_can::dbc::Database;
use hilrig_capture::CanFrame;
use hilrig_gnss::framer::nmea_sentence;
use hilrig_stamp::UtcNanos;
use nalgebra::{Point3, Vector3};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Bytes with the host time (ns) at which the logger receives them.
pub(super) type Timed = (i64, Vec<u8>);

/// Why a sensor's stream cannot be synthesized.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    /// A noise that is not a distribution (a negative or non-finite sigma).
    #[error("{0}")]
    Noise(#[from] rand_distr::NormalError),
    /// A heading stream without a rate, or with a negative noise.
    #[error("[heading] rate_hz = {rate_hz} and sigma_deg = {sigma_deg}: the rate must be positive and the noise not negative")]
    Heading {
        /// Its rate, Hz.
        rate_hz: f64,
        /// Its noise, deg.
        sigma_deg: f64,
    },
    /// A heading source synth does not write.
    #[error("synth writes the heading as THS, HDT, PASHR or PSTI,036; the rig's source is {0:?}")]
    HeadingSource(&'static str),
    /// The rig's CAN mapping has no speed.
    #[error("the rig's [can.ego] has no speed")]
    NoCanSpeed,
    /// The DBC lacks a message the mapping names.
    #[error("DBC has no message '{0}'")]
    NoDbcMessage(String),
    /// A DBC message longer than a CAN frame.
    #[error("message {0} does not fit a CAN frame")]
    FrameTooLong(String),
}

/// What both streams follow: the true drive and the faults to inject. Errors say what input is
/// wrong ([`StreamError`]), for the caller to wrap.
pub(super) struct Streams<'a> {
    /// The true drive.
    pub driven: &'a Driven,
    /// Faults to inject.
    pub faults: &'a Faults,
    /// Human variation and reference errors on.
    pub errors: bool,
    /// The drive's start and end.
    pub span: (UtcNanos, UtcNanos),
    /// The scene's origin (WGS84 of the local frame).
    pub origin: &'a Wgs84,
}

impl Streams<'_> {
    /// Seconds since the drive's start.
    fn since_start(&self, t: UtcNanos) -> f64 {
        (t.0 - self.span.0 .0) as f64 * 1e-9
    }

    /// GNSS fixes of the antenna (lever arm from the rig, plus any injected antenna error) with
    /// RTK noise: serial byte chunks with their receive times (ns), and the sentence count.
    pub(super) fn gnss(
        &self,
        gs: &GnssStream,
        gnss_cfg: &GnssConfig,
        grng: &mut ChaCha8Rng,
    ) -> Result<(Vec<Timed>, u64), StreamError> {
        let (driven, faults, errors) = (self.driven, self.faults, self.errors);
        let (start, end) = self.span;
        let mut events = Vec::new();
        let mut sentences = 0u64;
        // GNSS: fixes of the antenna (lever arm from the rig) with RTK noise (Gauss-Markov).
        let enu = Enu::new(self.origin);
        let dt = 1.0 / gs.rate_hz;
        let phi = (-dt / gs.correlation_s.max(1e-3)).exp();
        let drive_h = (1.0 - phi * phi).sqrt() * gs.sigma_horizontal_m;
        let drive_v = (1.0 - phi * phi).sqrt() * gs.sigma_vertical_m;
        let unit = Normal::new(0.0, 1.0)?;
        let mut noise = Vector3::new(
            unit.sample(grng) * gs.sigma_horizontal_m,
            unit.sample(grng) * gs.sigma_horizontal_m,
            unit.sample(grng) * gs.sigma_vertical_m,
        );
        // Where the antenna really is (the rig file's lever arm plus any injected error).
        let lever = Vector3::new(
            gnss_cfg.antenna.x + faults.antenna_error_m[0],
            gnss_cfg.antenna.y + faults.antenna_error_m[1],
            gnss_cfg.antenna.z + faults.antenna_error_m[2],
        );
        let offset_ns = (faults.gnss_time_offset_ms * 1e6).round() as i64;
        let step_ns = (1e9 / gs.rate_hz).round() as i64;
        let mut t = UtcNanos(start.0 + (step_ns - start.0.rem_euclid(step_ns)) % step_ns);
        let mut hint = 0;
        while t <= end {
            // A fix labelled `t` describes the instant `t - offset` (a receiver time offset).
            let Some(p) = driven.ego.sample_at(UtcNanos(t.0 - offset_ns), &mut hint) else {
                t = UtcNanos(t.0 + step_ns);
                continue;
            };
            let ts = self.since_start(t);
            let rtk_fault = faults
                .rtk
                .iter()
                .find(|f| ts >= f.from_s && ts < f.to_s)
                .map(|f| f.quality);
            let spike = faults
                .sigma_spike
                .iter()
                .find(|f| ts >= f.from_s && ts < f.to_s)
                .map(|f| f.sigma_m);
            // Degraded solutions: float about 0.2 m, DGNSS 0.5 m, autonomous 1.5 m (1 sigma).
            let (quality, sigma_h, sigma_v) = match (rtk_fault, spike) {
                (Some(q), _) => {
                    let s = match q {
                        5 => 0.20,
                        2 => 0.50,
                        _ => 1.50,
                    };
                    (q, s, 2.0 * s)
                }
                (None, Some(s)) => (4, s, 2.0 * s),
                (None, None) => (4, gs.sigma_horizontal_m, gs.sigma_vertical_m),
            };
            let extra = if errors && sigma_h > gs.sigma_horizontal_m {
                Vector3::new(
                    unit.sample(grng) * sigma_h,
                    unit.sample(grng) * sigma_h,
                    unit.sample(grng) * sigma_v,
                )
            } else {
                Vector3::zeros()
            };
            noise = Vector3::new(
                phi * noise.x + drive_h * unit.sample(grng),
                phi * noise.y + drive_h * unit.sample(grng),
                phi * noise.z + drive_v * unit.sample(grng),
            );
            // A jump: the epoch nearest `at_s` displaced, unknown to the receiver.
            let step_s = step_ns as f64 * 1e-9;
            let jump = faults
                .position_jump
                .iter()
                .filter(|j| (ts - j.at_s).abs() < step_s / 2.0)
                .fold(Vector3::zeros(), |acc, j| {
                    acc + Vector3::new(j.offset_m[0], j.offset_m[1], 0.0)
                });
            let antenna = p.isometry().transform_point(&Point3::from(lever)).coords
                + if errors { noise } else { Vector3::zeros() }
                + extra
                + jump;
            let w = enu.to_wgs84(&antenna);
            let (hms_s, date) = hms(t);
            let ll = nmea_lat_lon(w.latitude_deg, w.longitude_deg);
            let mut vh = 0;
            let vel = driven.ego.velocity_at(t, &mut vh).unwrap_or_default();
            let sog_kn = vel.xy().norm() / 0.514_444;
            let cog = (90.0 - vel.y.atan2(vel.x).to_degrees()).rem_euclid(360.0);
            let alt = w.height_m - gs.geoid_separation_m;
            let age = faults
                .correction_age
                .iter()
                .find(|f| ts >= f.from_s && ts < f.to_s)
                .map_or("1.0".to_owned(), |f| format!("{:.1}", f.age_s));
            let body = [
                format!(
                    "GNGGA,{hms_s},{ll},{quality},14,0.7,{alt:.3},M,{:.3},M,{},{}",
                    gs.geoid_separation_m,
                    if quality >= 4 { age.as_str() } else { "" },
                    if quality >= 4 { "0042" } else { "" },
                ),
                format!("GNRMC,{hms_s},A,{ll},{sog_kn:.3},{cog:.2},{date},,,R"),
                format!(
                    "GNGST,{hms_s},{:.3},{:.3},{:.3},0.0,{:.3},{:.3},{:.3}",
                    (2.0 * sigma_h.powi(2) + sigma_v.powi(2)).sqrt(),
                    sigma_h,
                    sigma_h,
                    sigma_h,
                    sigma_h,
                    sigma_v
                ),
            ];
            let mut bytes = Vec::new();
            for b in &body {
                bytes.extend(nmea_sentence(b).bytes());
                sentences += 1;
            }
            let lat_ns = gs.latency_ms * 1e6
                + if errors {
                    (unit.sample(grng) * gs.jitter_ms * 1e6).abs()
                } else {
                    0.0
                };
            // A silent receiver: the epoch is computed (the noise goes on) but not sent.
            if faults.gnss_gap.iter().any(|w| w.contains(ts)) {
                sentences -= body.len() as u64;
            } else {
                events.push((t.0 + lat_ns as i64, bytes));
            }
            t = UtcNanos(t.0 + step_ns);
        }

        Ok((events, sentences))
    }

    /// The rig's heading source's reports of the vehicle's true heading (plus the source's
    /// mounting and misalignment, and noise): serial byte chunks with their receive times,
    /// and the sentence count. Written as the rig's message: THS (mode A, or E where the
    /// drive says the source dead-reckons), HDT, PASHR (with its sigma) or PSTI,036.
    ///
    /// THS and HDT carry no time of their own: a receiver writes them in its epoch's burst of
    /// sentences, and a reader tags them with that epoch. They are written so here, at the
    /// GNSS rate just after the epoch's GGA, whatever the drive's heading rate says.
    pub(super) fn heading(
        &self,
        hs: &HeadingStream,
        gs: &GnssStream,
        cfg: &crate::rig::HeadingConfig,
        rng: &mut ChaCha8Rng,
    ) -> Result<(Vec<Timed>, u64), StreamError> {
        use crate::rig::HeadingSource as H;
        let in_epoch = matches!(cfg.source, H::Ths | H::Hdt);
        let (rate_hz, latency_ms) = if in_epoch {
            (gs.rate_hz, gs.latency_ms + 6.0 * gs.jitter_ms + 1.0)
        } else {
            (hs.rate_hz, hs.latency_ms)
        };
        if !(hs.rate_hz > 0.0 && hs.sigma_deg >= 0.0) {
            return Err(StreamError::Heading {
                rate_hz: hs.rate_hz,
                sigma_deg: hs.sigma_deg,
            });
        }
        let noise = Normal::new(0.0, hs.sigma_deg)?;
        let (start, end) = self.span;
        let step_ns = (1e9 / rate_hz).round() as i64;
        let mut t = UtcNanos(start.0 + (step_ns - start.0.rem_euclid(step_ns)) % step_ns);
        let mut hint = 0;
        let mut events = Vec::new();
        let mut sentences = 0;
        let mut last: Option<f64> = None;
        while t <= end {
            let Some(p) = self.driven.ego.sample_at(t, &mut hint) else {
                t = UtcNanos(t.0 + step_ns);
                continue;
            };
            let ts = self.since_start(t);
            // The vehicle's heading clockwise from north, as the source's axis reads it.
            let true_heading = 90.0 - p.yaw.to_degrees() + cfg.yaw_offset_deg + hs.misalignment_deg;
            let mut h = true_heading + if self.errors { noise.sample(rng) } else { 0.0 };
            if hs.frozen.iter().any(|w| w.contains(ts)) {
                h = last.unwrap_or(h);
            }
            last = Some(h);
            let h = h.rem_euclid(360.0);
            let estimated = hs.estimated.iter().any(|w| w.contains(ts));
            let (hms_s, date) = hms(t);
            let body = match cfg.source {
                H::Ths => format!("GNTHS,{h:.3},{}", if estimated { 'E' } else { 'A' }),
                H::Hdt => format!("GNHDT,{h:.3},T"),
                H::Pashr => format!(
                    "PASHR,{hms_s},{h:.3},T,+0.00,+0.00,+0.00,0.000,0.000,{:.3},2,{}",
                    hs.sigma_deg.max(0.001),
                    if estimated { 2 } else { 4 }
                ),
                H::Psti036 => format!(
                    "PSTI,036,{hms_s},{date},{h:.3},0.00,0.00,{}",
                    if estimated { 'E' } else { 'R' }
                ),
                other => return Err(StreamError::HeadingSource(other.name())),
            };
            sentences += 1;
            events.push((
                t.0 + (latency_ms * 1e6).round() as i64,
                nmea_sentence(&body).into_bytes(),
            ));
            t = UtcNanos(t.0 + step_ns);
        }
        Ok((events, sentences))
    }

    /// CAN frames (SocketCAN encoding) with their receive times (ns): speed (with any injected
    /// scale), yaw rate and steering wheel angle through the rig's ego mapping.
    pub(super) fn can(
        &self,
        cs: &CanStream,
        can_cfg: &CanConfig,
        dbc: &Database,
        crng: &mut ChaCha8Rng,
    ) -> Result<Vec<Timed>, StreamError> {
        let (driven, faults, errors) = (self.driven, self.faults, self.errors);
        let (start, end) = self.span;
        let mut events = Vec::new();
        // CAN: ego motion from the rig's DBC mapping.
        let ego_map = &can_cfg.ego;
        let speed_map = ego_map.speed.as_ref().ok_or(StreamError::NoCanSpeed)?;
        let msg = dbc
            .message_by_name(&speed_map.message)
            .ok_or_else(|| StreamError::NoDbcMessage(speed_map.message.clone()))?;
        let index = |name: &str| msg.signals.iter().position(|s| s.name == name);
        let step_ns = (1e9 / cs.rate_hz).round() as i64;
        let mut t = UtcNanos(start.0 + step_ns / 2);
        let mut counter = 0u32;
        let mut hint = 0;
        while t <= end {
            let Some(seg) = driven.ego.segment(t, &mut hint) else {
                break;
            };
            // Speed and yaw rate at `t` itself (between the 10 ms samples), so that CAN carries no
            // timing error beyond its latency.
            let samples = driven.ego.samples();
            let f = if seg + 1 < samples.len() {
                (t.0 - samples[seg].t.0) as f64 / (samples[seg + 1].t.0 - samples[seg].t.0) as f64
            } else {
                0.0
            };
            let (m0, m1) = (
                driven.motion[seg],
                driven.motion[(seg + 1).min(samples.len() - 1)],
            );
            let (v, w) = (m0.0 + (m1.0 - m0.0) * f, m0.1 + (m1.1 - m0.1) * f);
            let noisy = |x: f64, s: f64, r: &mut ChaCha8Rng| {
                if errors {
                    x + Normal::new(0.0, s).map_or(0.0, |n| n.sample(r))
                } else {
                    x
                }
            };
            let mut values = Vec::new();
            let si_to = |m: &hilrig_can::ego::SignalMap, si: f64| m.unit.from_si(si / m.scale);
            if let Some(i) = index(&speed_map.signal) {
                let v_read = v * faults.can_speed_scale;
                // Backing up: a signed signal carries the sign; a magnitude with a sign flag
                // sets the flag; a magnitude alone (most cars, and this project's DBC) reads the
                // same as driving forward.
                let flag = speed_map.sign_signal.as_deref().and_then(index);
                let x = if v_read < 0.0 && (flag.is_some() || !can_be_negative(&msg.signals[i])) {
                    -v_read
                } else {
                    v_read
                };
                if let Some(f) = flag {
                    values.push((f, if v_read < 0.0 { 1.0 } else { 0.0 }));
                }
                values.push((i, si_to(speed_map, noisy(x, cs.speed_sigma_mps, crng))));
            }
            if let Some(m) = ego_map.yaw_rate.as_ref().filter(|m| m.message == msg.name) {
                if let Some(i) = index(&m.signal) {
                    values.push((i, si_to(m, noisy(w, cs.yaw_rate_sigma_rps, crng))));
                }
            }
            if let Some(m) = ego_map
                .steering_wheel_angle
                .as_ref()
                .filter(|m| m.message == msg.name)
            {
                if let Some(i) = index(&m.signal) {
                    // Bicycle model: wheel angle atan(L κ), steering ratio 15, wheelbase 2.7 m.
                    let kappa = if v.abs() > 0.1 { w / v } else { 0.0 };
                    values.push((i, si_to(m, (2.7 * kappa).atan() * 15.0)));
                }
            }
            if let Some(i) = index("Counter") {
                values.push((i, f64::from(counter % 16)));
            }
            counter += 1;
            let data = msg.encode(&values);
            let frame = CanFrame::new(msg.id, msg.extended, &data)
                .ok_or_else(|| StreamError::FrameTooLong(msg.name.clone()))?;
            if !faults
                .can_gap
                .iter()
                .any(|w| w.contains(self.since_start(t)))
            {
                events.push((t.0 + (cs.latency_ms * 1e6) as i64, frame.encode_socketcan()));
            }
            t = UtcNanos(t.0 + step_ns);
        }

        Ok(events)
    }
}

/// NMEA time (hhmmss.ss) and date (ddmmyy) of `t`.
pub(super) fn hms(t: UtcNanos) -> (String, String) {
    let tod = t.0.rem_euclid(86_400_000_000_000);
    let days = t.0.div_euclid(86_400_000_000_000);
    let (y, m, d) = hilrig_stamp::civil::civil_from_days(days).unwrap_or((1970, 1, 1));
    (
        format!(
            "{:02}{:02}{:02}.{:02}",
            tod / 3_600_000_000_000,
            tod / 60_000_000_000 % 60,
            tod / 1_000_000_000 % 60,
            tod / 10_000_000 % 100
        ),
        format!("{d:02}{m:02}{:02}", y.rem_euclid(100)),
    )
}

/// NMEA latitude and longitude fields (ddmm.mmmmmmm,N,dddmm.mmmmmmm,E).
pub(super) fn nmea_lat_lon(lat: f64, lon: f64) -> String {
    let f = |v: f64, width: usize| {
        let a = v.abs();
        let deg = a.floor();
        let min = (a - deg) * 60.0;
        format!("{:0width$}{:010.7}", deg as i64, min, width = width)
    };
    format!(
        "{},{},{},{}",
        f(lat, 2),
        if lat >= 0.0 { 'N' } else { 'S' },
        f(lon, 3),
        if lon >= 0.0 { 'E' } else { 'W' }
    )
}
/// Whether a DBC signal can carry a negative value: a signed or floating-point one, or an
/// unsigned one whose offset or factor reaches below zero.
fn can_be_negative(s: &hilrig_can::dbc::SignalDef) -> bool {
    match s.repr {
        hilrig_can::dbc::Repr::Unsigned => s.offset < 0.0 || s.factor < 0.0,
        _ => true,
    }
}
