//! Ego motion from CAN: which DBC signals give speed, yaw rate, steering angle and wheel
//! speeds, in which units and with which sign, turned into SI samples in one convention.
//!
//! Convention (ISO 8855 vehicle axes): speed in m/s, positive forward; yaw rate in rad/s,
//! positive counter-clockwise seen from above (turning left); steering wheel angle in rad,
//! positive to the left; wheel speeds in m/s, front-left, front-right, rear-left, rear-right.
//!
//! The mapping is part of the rig file (`[can.ego]`, TOML, unknown keys rejected). Vehicles
//! encode signs in two ways, both supported: a signed signal (flip it with `scale = -1` when
//! the vehicle's positive direction is the other one), or a magnitude plus a separate sign
//! flag (`sign_signal`, 1 = negative, as VW's `*_VZ_*` signals).

use crate::dbc::{Database, Decoded};
use hilrig_stamp::UtcNanos;
use serde::Deserialize;

/// Physical unit of a mapped signal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
pub enum Unit {
    /// Metres per second.
    #[serde(rename = "m/s")]
    MetersPerSecond,
    /// Kilometres per hour.
    #[serde(rename = "km/h")]
    KilometersPerHour,
    /// Miles per hour.
    #[serde(rename = "mph")]
    MilesPerHour,
    /// Radians per second.
    #[serde(rename = "rad/s")]
    RadiansPerSecond,
    /// Degrees per second.
    #[serde(rename = "deg/s")]
    DegreesPerSecond,
    /// Radians.
    #[serde(rename = "rad")]
    Radians,
    /// Degrees.
    #[serde(rename = "deg")]
    Degrees,
}

impl Unit {
    /// A value in this unit in SI (m/s, rad/s, rad).
    pub fn to_si(self, v: f64) -> f64 {
        match self {
            Unit::MetersPerSecond | Unit::RadiansPerSecond | Unit::Radians => v,
            Unit::KilometersPerHour => v / 3.6,
            Unit::MilesPerHour => v * 0.447_04,
            Unit::DegreesPerSecond | Unit::Degrees => v.to_radians(),
        }
    }

    /// An SI value in this unit (inverse of [`Unit::to_si`]).
    pub fn from_si(self, v: f64) -> f64 {
        match self {
            Unit::MetersPerSecond | Unit::RadiansPerSecond | Unit::Radians => v,
            Unit::KilometersPerHour => v * 3.6,
            Unit::MilesPerHour => v / 0.447_04,
            Unit::DegreesPerSecond | Unit::Degrees => v.to_degrees(),
        }
    }
}

/// Where one quantity comes from.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SignalMap {
    /// DBC message name.
    pub message: String,
    /// DBC signal name.
    pub signal: String,
    /// Unit of the signal's physical value.
    pub unit: Unit,
    /// Multiplies the value after unit conversion (use -1 when the vehicle's positive direction
    /// is opposite to the convention above).
    #[serde(default = "one")]
    pub scale: f64,
    /// A 1-bit signal of the same message that makes the value negative when it is 1.
    #[serde(default)]
    pub sign_signal: Option<String>,
}

fn one() -> f64 {
    1.0
}

/// The ego mapping of a rig file.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EgoMapping {
    /// Vehicle speed.
    pub speed: Option<SignalMap>,
    /// Yaw rate.
    pub yaw_rate: Option<SignalMap>,
    /// Steering wheel angle.
    pub steering_wheel_angle: Option<SignalMap>,
    /// Wheel speeds: front-left, front-right, rear-left, rear-right.
    pub wheel_speeds: Option<[SignalMap; 4]>,
}

/// One ego quantity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Quantity {
    /// Speed, m/s.
    Speed,
    /// Yaw rate, rad/s.
    YawRate,
    /// Steering wheel angle, rad.
    SteeringWheelAngle,
    /// Wheel speed (index 0-3: FL, FR, RL, RR), m/s.
    WheelSpeed(u8),
}

/// A measured ego quantity in SI units and the ISO 8855 convention.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EgoSample {
    /// Receive time of the frame.
    pub time: UtcNanos,
    /// Which quantity.
    pub quantity: Quantity,
    /// Value.
    pub value: f64,
}

/// A mapping entry that does not match the DBC.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("ego mapping {quantity}: {what}")]
pub struct MappingError {
    /// Which entry.
    pub quantity: String,
    /// What is wrong.
    pub what: String,
}

struct Resolved {
    quantity: Quantity,
    id: (u32, bool),
    signal: usize,
    sign: Option<usize>,
    unit: Unit,
    scale: f64,
}

/// Turns decoded frames into ego samples.
pub struct EgoTracker {
    entries: Vec<Resolved>,
}

impl EgoTracker {
    /// Checks the mapping against the DBC (messages and signals must exist).
    pub fn new(mapping: &EgoMapping, db: &Database) -> Result<EgoTracker, MappingError> {
        let mut wanted: Vec<(Quantity, &SignalMap)> = Vec::new();
        if let Some(m) = &mapping.speed {
            wanted.push((Quantity::Speed, m));
        }
        if let Some(m) = &mapping.yaw_rate {
            wanted.push((Quantity::YawRate, m));
        }
        if let Some(m) = &mapping.steering_wheel_angle {
            wanted.push((Quantity::SteeringWheelAngle, m));
        }
        if let Some(ws) = &mapping.wheel_speeds {
            for (i, m) in ws.iter().enumerate() {
                wanted.push((Quantity::WheelSpeed(i as u8), m));
            }
        }
        let mut entries = Vec::new();
        for (quantity, m) in wanted {
            let err = |what: String| MappingError {
                quantity: format!("{quantity:?}"),
                what,
            };
            let msg = db
                .message_by_name(&m.message)
                .ok_or_else(|| err(format!("message {} is not in the DBC", m.message)))?;
            let find = |name: &str| {
                msg.signals
                    .iter()
                    .position(|s| s.name == name)
                    .ok_or_else(|| err(format!("signal {name} is not in message {}", m.message)))
            };
            let signal = find(&m.signal)?;
            let sign = m.sign_signal.as_deref().map(find).transpose()?;
            if !m.scale.is_finite() || m.scale == 0.0 {
                return Err(err(format!(
                    "scale {} must be finite and not zero",
                    m.scale
                )));
            }
            entries.push(Resolved {
                quantity,
                id: (msg.id, msg.extended),
                signal,
                sign,
                unit: m.unit,
                scale: m.scale,
            });
        }
        Ok(EgoTracker { entries })
    }

    /// Samples from one decoded frame (none when the frame carries no mapped signal).
    pub fn handle(&self, time: UtcNanos, d: &Decoded<'_>, out: &mut Vec<EgoSample>) {
        let id = (d.message.id, d.message.extended);
        for e in self.entries.iter().filter(|e| e.id == id) {
            let get = |i: usize| d.values.iter().find(|(j, _)| *j == i).map(|(_, v)| *v);
            let Some(mut v) = get(e.signal) else { continue };
            if let Some(s) = e.sign {
                match get(s) {
                    Some(flag) if flag != 0.0 => v = -v,
                    Some(_) => {}
                    None => continue,
                }
            }
            out.push(EgoSample {
                time,
                quantity: e.quantity,
                value: e.unit.to_si(v) * e.scale,
            });
        }
    }
}
