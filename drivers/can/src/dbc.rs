//! A DBC file compiled for fast decoding and encoding.

use crate::codec::{extract, fits, insert, sign_extend, Order};
use can_dbc::{
    ByteOrder, MultiplexIndicator, SignalExtendedValueType, ValueDescription, ValueType,
};
use hilrig_capture::CanFrame;
use std::collections::{BTreeMap, HashMap};

/// A DBC file that cannot be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DbcError {
    /// The file could not be read.
    #[error("cannot read DBC file {path}: {source}")]
    Io {
        /// Path.
        path: String,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// can-dbc rejected the text.
    #[error("DBC parse error: {0}")]
    Parse(String),
    /// A signal does not fit its message or is otherwise unusable.
    #[error("message {message} ({id:#x}) signal {signal}: {what}")]
    Signal {
        /// Message name.
        message: String,
        /// Raw id.
        id: u32,
        /// Signal name.
        signal: String,
        /// What is wrong.
        what: String,
    },
}

/// Value representation of a signal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Repr {
    /// Unsigned integer.
    Unsigned,
    /// Two's complement integer.
    Signed,
    /// IEEE 754 single (32 bits).
    Float32,
    /// IEEE 754 double (64 bits).
    Float64,
}

/// When a signal is present in a frame.
#[derive(Clone, Debug, PartialEq)]
pub enum Presence {
    /// Always.
    Always,
    /// When the multiplexor signal (index into the message's signals) has one of these value
    /// ranges (inclusive).
    When {
        /// Index of the multiplexor signal.
        multiplexor: usize,
        /// Inclusive ranges of multiplexor values.
        ranges: Vec<(u64, u64)>,
    },
}

/// One signal, ready to decode.
#[derive(Clone, Debug, PartialEq)]
pub struct SignalDef {
    /// Name.
    pub name: String,
    /// DBC start bit.
    pub start: u32,
    /// Length in bits.
    pub size: u32,
    /// Byte order.
    pub order: Order,
    /// Representation.
    pub repr: Repr,
    /// Physical = raw × factor + offset.
    pub factor: f64,
    /// Physical offset.
    pub offset: f64,
    /// Unit text.
    pub unit: String,
    /// When the signal is present.
    pub presence: Presence,
    /// Whether other signals are multiplexed by this one.
    pub is_multiplexor: bool,
    /// Value table (raw value -> text).
    pub values: BTreeMap<i64, String>,
}

/// One message.
#[derive(Clone, Debug, PartialEq)]
pub struct MessageDef {
    /// Name.
    pub name: String,
    /// Identifier (11 or 29 bits).
    pub id: u32,
    /// Extended identifier.
    pub extended: bool,
    /// Payload length in bytes.
    pub size: usize,
    /// Signals in DBC order.
    pub signals: Vec<SignalDef>,
}

/// A decoded frame: the message and its active signals' physical values.
#[derive(Clone, Debug, PartialEq)]
pub struct Decoded<'a> {
    /// The message definition.
    pub message: &'a MessageDef,
    /// (signal index, physical value) of every signal present in this frame.
    pub values: Vec<(usize, f64)>,
}

/// A compiled DBC.
#[derive(Clone, Debug, Default)]
pub struct Database {
    messages: Vec<MessageDef>,
    by_id: HashMap<(u32, bool), usize>,
}

fn order(b: &ByteOrder) -> Order {
    match b {
        ByteOrder::LittleEndian => Order::Intel,
        ByteOrder::BigEndian => Order::Motorola,
    }
}

impl Database {
    /// Parses and compiles DBC text.
    pub fn from_dbc_text(text: &str) -> Result<Database, DbcError> {
        let dbc = can_dbc::Dbc::try_from(text).map_err(|e| DbcError::Parse(format!("{e:?}")))?;
        Database::compile(&dbc)
    }

    /// Reads a DBC file.
    pub fn from_file(path: &std::path::Path) -> Result<Database, DbcError> {
        let bytes = std::fs::read(path).map_err(|e| DbcError::Io {
            path: path.display().to_string(),
            source: e,
        })?;
        // DBC files are often Windows-1252; every byte below 0x80 is ASCII, which is all that
        // identifiers use, so a lossy conversion only touches comments and value texts.
        let text = String::from_utf8_lossy(&bytes);
        Database::from_dbc_text(&text)
    }

    fn compile(dbc: &can_dbc::Dbc) -> Result<Database, DbcError> {
        let mut db = Database::default();
        for m in &dbc.messages {
            let (id, extended) = match m.id {
                can_dbc::MessageId::Standard(id) => (u32::from(id), false),
                can_dbc::MessageId::Extended(id) => (id, true),
            };
            // opendbc marks pseudo messages (e.g. VECTOR__INDEPENDENT_SIG_MSG) with ids above the
            // 11-bit range without the extended flag; they never appear on a bus.
            if !extended && id > 0x7FF {
                continue;
            }
            let size = m.size as usize;
            let mut signals = Vec::with_capacity(m.signals.len());
            let names: Vec<&str> = m.signals.iter().map(|s| s.name.as_str()).collect();
            let simple_mux = m.signals.iter().position(|s| {
                matches!(
                    s.multiplexer_indicator,
                    MultiplexIndicator::Multiplexor
                        | MultiplexIndicator::MultiplexorAndMultiplexedSignal(_)
                )
            });
            for s in &m.signals {
                let err = |what: String| DbcError::Signal {
                    message: m.name.clone(),
                    id,
                    signal: s.name.clone(),
                    what,
                };
                let repr = match dbc.extended_value_type_for_signal(m.id, &s.name) {
                    Some(SignalExtendedValueType::IEEEfloat32Bit) => Repr::Float32,
                    Some(SignalExtendedValueType::IEEEdouble64bit) => Repr::Float64,
                    _ => match s.value_type {
                        ValueType::Signed => Repr::Signed,
                        ValueType::Unsigned => Repr::Unsigned,
                    },
                };
                let (start, bits) = (s.start_bit as u32, s.size as u32);
                if !fits(order(&s.byte_order), start, bits, size.max(8)) {
                    return Err(err(format!(
                        "{bits} bits from bit {start} do not fit {size} bytes"
                    )));
                }
                let presence = match s.multiplexer_indicator {
                    MultiplexIndicator::MultiplexedSignal(v)
                    | MultiplexIndicator::MultiplexorAndMultiplexedSignal(v) => {
                        // Extended multiplexing (SG_MUL_VAL_) overrides the simple m<v> rule.
                        match dbc
                            .extended_multiplex
                            .iter()
                            .find(|e| e.message_id == m.id && e.signal_name == s.name)
                        {
                            Some(e) => {
                                let mux = names
                                    .iter()
                                    .position(|n| *n == e.multiplexor_signal_name)
                                    .ok_or_else(|| {
                                        err(format!(
                                            "multiplexor {} is not in the message",
                                            e.multiplexor_signal_name
                                        ))
                                    })?;
                                let ranges = dbc
                                    .extended_multiplex
                                    .iter()
                                    .filter(|x| x.message_id == m.id && x.signal_name == s.name)
                                    .flat_map(|x| {
                                        x.mappings.iter().map(|r| (r.min_value, r.max_value))
                                    })
                                    .collect();
                                Presence::When {
                                    multiplexor: mux,
                                    ranges,
                                }
                            }
                            None => {
                                let mux = simple_mux
                                    .filter(|&i| m.signals[i].name != s.name)
                                    .ok_or_else(|| {
                                        err("multiplexed, but the message has no multiplexor"
                                            .into())
                                    })?;
                                Presence::When {
                                    multiplexor: mux,
                                    ranges: vec![(v, v)],
                                }
                            }
                        }
                    }
                    _ => Presence::Always,
                };
                let values = dbc
                    .value_descriptions
                    .iter()
                    .find_map(|vd| match vd {
                        ValueDescription::Signal {
                            message_id,
                            name,
                            value_descriptions,
                        } if *message_id == m.id && *name == s.name => Some(
                            value_descriptions
                                .iter()
                                .map(|v| (v.id, v.description.clone()))
                                .collect(),
                        ),
                        _ => None,
                    })
                    .unwrap_or_default();
                signals.push(SignalDef {
                    name: s.name.clone(),
                    start,
                    size: bits,
                    order: order(&s.byte_order),
                    repr,
                    factor: s.factor,
                    offset: s.offset,
                    unit: s.unit.clone(),
                    presence,
                    is_multiplexor: matches!(
                        s.multiplexer_indicator,
                        MultiplexIndicator::Multiplexor
                            | MultiplexIndicator::MultiplexorAndMultiplexedSignal(_)
                    ),
                    values,
                });
            }
            // Extended multiplexing can name any signal as multiplexor.
            for i in 0..signals.len() {
                if let Presence::When { multiplexor, .. } = signals[i].presence {
                    signals[multiplexor].is_multiplexor = true;
                }
            }
            db.by_id.insert((id, extended), db.messages.len());
            db.messages.push(MessageDef {
                name: m.name.clone(),
                id,
                extended,
                size,
                signals,
            });
        }
        Ok(db)
    }

    /// All messages.
    pub fn messages(&self) -> &[MessageDef] {
        &self.messages
    }

    /// The message with this id.
    pub fn message(&self, id: u32, extended: bool) -> Option<&MessageDef> {
        self.by_id.get(&(id, extended)).map(|&i| &self.messages[i])
    }

    /// The message with this name.
    pub fn message_by_name(&self, name: &str) -> Option<&MessageDef> {
        self.messages.iter().find(|m| m.name == name)
    }

    /// Decodes a frame: `None` when the id is not in the database or the frame is a remote or
    /// error frame. Signals that do not fit a shorter-than-declared payload are left out.
    pub fn decode(&self, frame: &CanFrame) -> Option<Decoded<'_>> {
        if frame.rtr || frame.error {
            return None;
        }
        let message = self.message(frame.id, frame.extended)?;
        let mut values = Vec::with_capacity(message.signals.len());
        message.decode_into(frame.data(), &mut values);
        Some(Decoded { message, values })
    }
}

impl MessageDef {
    /// Raw (unscaled) value of a signal, `None` when it does not fit the payload.
    pub fn raw(&self, data: &[u8], index: usize) -> Option<u64> {
        let s = &self.signals[index];
        fits(s.order, s.start, s.size, data.len()).then(|| extract(data, s.order, s.start, s.size))
    }

    fn present(&self, data: &[u8], s: &SignalDef) -> bool {
        match &s.presence {
            Presence::Always => true,
            Presence::When {
                multiplexor,
                ranges,
            } => {
                let Some(mux) = self.raw(data, *multiplexor) else {
                    return false;
                };
                // A multiplexor that is itself multiplexed must be present too.
                self.present(data, &self.signals[*multiplexor])
                    && ranges.iter().any(|&(lo, hi)| mux >= lo && mux <= hi)
            }
        }
    }

    /// Appends (signal index, physical value) of the signals present in `data`.
    pub fn decode_into(&self, data: &[u8], out: &mut Vec<(usize, f64)>) {
        for (i, s) in self.signals.iter().enumerate() {
            if !self.present(data, s) {
                continue;
            }
            let Some(raw) = self.raw(data, i) else {
                continue;
            };
            out.push((i, s.physical(raw)));
        }
    }

    /// Encodes physical values into a payload of the message's size; signals not given are 0
    /// raw. Multiplexed signals whose multiplexor value does not select them are skipped.
    pub fn encode(&self, values: &[(usize, f64)]) -> Vec<u8> {
        let mut data = vec![0u8; self.size];
        // Multiplexors first, so that presence can be judged.
        for pass in [true, false] {
            for &(i, v) in values {
                let s = &self.signals[i];
                if s.is_multiplexor != pass || !fits(s.order, s.start, s.size, data.len()) {
                    continue;
                }
                if !pass && !self.present(&data, s) {
                    continue;
                }
                insert(&mut data, s.order, s.start, s.size, s.raw_from_physical(v));
            }
        }
        data
    }
}

impl SignalDef {
    /// Physical value of a raw value.
    pub fn physical(&self, raw: u64) -> f64 {
        let x = match self.repr {
            Repr::Unsigned => raw as f64,
            Repr::Signed => sign_extend(raw, self.size) as f64,
            Repr::Float32 => f64::from(f32::from_bits(raw as u32)),
            Repr::Float64 => f64::from_bits(raw),
        };
        x * self.factor + self.offset
    }

    /// Raw value for a physical value (rounded to the nearest step, saturated to the signal's
    /// range), in the low `size` bits.
    pub fn raw_from_physical(&self, v: f64) -> u64 {
        let scaled = if self.factor != 0.0 {
            (v - self.offset) / self.factor
        } else {
            0.0
        };
        let mask = if self.size >= 64 {
            u64::MAX
        } else {
            (1u64 << self.size) - 1
        };
        match self.repr {
            Repr::Float32 => u64::from((scaled as f32).to_bits()),
            Repr::Float64 => scaled.to_bits(),
            Repr::Unsigned => {
                let max = mask as f64;
                scaled.round().clamp(0.0, max) as u64
            }
            Repr::Signed => {
                let half = if self.size >= 64 {
                    i64::MAX as f64
                } else {
                    ((1u64 << (self.size - 1)) - 1) as f64
                };
                let r = scaled.round().clamp(-half - 1.0, half) as i64;
                (r as u64) & mask
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DBC: &str = r#"VERSION ""

BO_ 257 ESP_02: 8 Gateway
 SG_ YawRate : 40|14@1+ (0.01,0) [0|163.84] "deg/s" XXX
 SG_ YawRate_Sign : 54|1@1+ (1,0) [0|1] "" XXX
 SG_ Temp : 7|12@0- (0.5,-10) [0|0] "C" XXX

BO_ 2148676694 Mux: 8 X
 SG_ Sel M : 0|8@1+ (1,0) [0|0] "" X
 SG_ A m1 : 8|16@1+ (1,0) [0|0] "" X
 SG_ B m2 : 8|16@1- (1,0) [0|0] "" X

VAL_ 257 YawRate_Sign 0 "left" 1 "right" ;
"#;

    #[test]
    fn ieee_float_signals_and_fd_payloads() {
        let dbc = "VERSION \"\"\n\nBO_ 2147484160 Fd: 16 X\n SG_ F32 : 0|32@1- (1,0) [0|0] \"\" X\n SG_ F64 : 64|64@1- (2,1) [0|0] \"\" X\n\nSIG_VALTYPE_ 2147484160 F32 : 1;\nSIG_VALTYPE_ 2147484160 F64 : 2;\n";
        let db = Database::from_dbc_text(dbc).unwrap();
        let m = db.message(0x200, true).unwrap();
        assert_eq!(m.signals[0].repr, Repr::Float32);
        assert_eq!(m.signals[1].repr, Repr::Float64);
        let data = m.encode(&[(0, -1.5), (1, 7.25)]);
        assert_eq!(&data[..4], &(-1.5f32).to_bits().to_le_bytes());
        assert_eq!(
            &data[8..16],
            &3.125f64.to_bits().to_le_bytes(),
            "(7.25 - 1) / 2"
        );
        let f = CanFrame::new_fd(0x200, true, &data, true).unwrap();
        assert_eq!(db.decode(&f).unwrap().values, vec![(0, -1.5), (1, 7.25)]);
    }

    #[test]
    fn decode_encode_intel_motorola_and_mux() {
        let db = Database::from_dbc_text(DBC).unwrap();
        let m = db.message(257, false).unwrap();
        assert_eq!(
            m.signals[1].values.get(&1).map(String::as_str),
            Some("right")
        );
        let data = m.encode(&[(0, 12.34), (1, 1.0), (2, -20.5)]);
        let f = CanFrame::new(257, false, &data).unwrap();
        let d = db.decode(&f).unwrap();
        assert_eq!(d.values, vec![(0, 12.34), (1, 1.0), (2, -20.5)]);
        let mux = db
            .message(0x76_6556 & 0x1fff_ffff, true)
            .or_else(|| db.messages().iter().find(|m| m.name == "Mux"))
            .unwrap();
        let data = mux.encode(&[(0, 2.0), (1, 5.0), (2, -3.0)]);
        let f = CanFrame::new(mux.id, mux.extended, &data).unwrap();
        let d = db.decode(&f).unwrap();
        assert_eq!(
            d.values,
            vec![(0, 2.0), (2, -3.0)],
            "only the selected signal"
        );
    }
}
