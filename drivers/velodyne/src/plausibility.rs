//! Does the data look like the model we decode it as?
//!
//! The product byte is not always right (early VLP-16 firmware writes 0x21, the HDL-32E byte), and
//! decoding with the wrong model puts every point at a wrong elevation without any error. The
//! packet rate gives the model away: each packet covers a fixed number of firing cycles, so the
//! spacing of the sensor timestamps is 552.96 µs for an HDL-32E but 1327.10 µs for a VLP-16
//! (single return). This check compares the median spacing with what the model implies.

use crate::decode::Decoder;
use crate::model::Model;
use crate::packet::{DataPacket, ReturnMode};

/// Packets looked at before judging.
pub const SAMPLE: usize = 200;

/// Collects timestamp spacing of the first packets of a stream.
#[derive(Clone, Debug, Default)]
pub struct ModelCheck {
    last_us: Option<u32>,
    mode: Option<ReturnMode>,
    deltas: Vec<u32>,
}

/// The outcome when the data do not fit the model.
#[derive(Clone, Debug, PartialEq)]
pub struct Mismatch {
    /// The model decoded as.
    pub claimed: Model,
    /// Median timestamp spacing observed, µs.
    pub observed_period_us: f64,
    /// Spacing the claimed model implies, µs.
    pub expected_period_us: f64,
    /// Models whose spacing fits.
    pub candidates: Vec<Model>,
}

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the geometry does not look like a {}: packets are {:.2} µs apart, a {} sends one every {:.2} µs",
            self.claimed, self.observed_period_us, self.claimed, self.expected_period_us
        )?;
        if !self.candidates.is_empty() {
            let names: Vec<&str> = self.candidates.iter().map(|m| m.name()).collect();
            write!(
                f,
                "; it fits {} (force it with --model {})",
                names.join(" or "),
                names[0]
            )?;
        }
        Ok(())
    }
}

impl ModelCheck {
    /// Observes a packet.
    pub fn observe(&mut self, pkt: &DataPacket) {
        if self.deltas.len() >= SAMPLE {
            return;
        }
        if self.mode.is_none() {
            self.mode = pkt.return_mode.mode();
        }
        if let Some(last) = self.last_us.replace(pkt.timestamp_us) {
            let d = pkt.timestamp_us.wrapping_sub(last);
            // Ignore the hour wrap, losses and reordering: only plausible single steps.
            if d > 0 && d < 5_000 {
                self.deltas.push(d);
            }
        }
    }

    /// `None` while undecided or when the model fits; a mismatch otherwise.
    pub fn verdict(&self, claimed: Model) -> Option<Mismatch> {
        if self.deltas.len() < 20 {
            return None;
        }
        let mut d = self.deltas.clone();
        d.sort_unstable();
        let median = f64::from(d[d.len() / 2]);
        let mode = self.mode.unwrap_or(ReturnMode::Strongest);
        let fits = |m: Model| {
            let p = Decoder::new(m).packet_period_us(mode);
            ((median - p) / p).abs() < 0.05
        };
        if fits(claimed) {
            return None;
        }
        Some(Mismatch {
            claimed,
            observed_period_us: median,
            expected_period_us: Decoder::new(claimed).packet_period_us(mode),
            candidates: Model::ALL.iter().copied().filter(|&m| fits(m)).collect(),
        })
    }
}
