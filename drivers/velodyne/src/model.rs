//! Sensor models: what the product byte says, how many lasers fire per block, when each fires,
//! and the geometry the manuals publish.
//!
//! Values are taken from Velodyne's user manuals (VLP-16 63-9243 Rev E, Puck Hi-Res 63-9318,
//! VLP-32C 63-9325, HDL-32E 63-9113): vertical angles, azimuth offsets and vertical offsets of
//! each laser, the firing cycle, and the distance resolution. A calibration file in the
//! ros-drivers YAML format overrides the geometry (see [`crate::calibration`]).

use std::fmt;
use std::str::FromStr;

/// A Velodyne sensor model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Model {
    /// VLP-16 ("Puck"): 16 lasers, ±15°.
    Vlp16,
    /// Puck Hi-Res: 16 lasers, ±10°.
    PuckHiRes,
    /// VLP-32C ("Ultra Puck"): 32 lasers, -25° to +15°, firing in pairs.
    Vlp32c,
    /// HDL-32E: 32 lasers, -30.67° to +10.67°.
    Hdl32e,
}

/// The factory byte of a data packet (byte 1205).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ProductId(pub u8);

impl ProductId {
    /// HDL-32E (also written by early VLP-16 firmware, see [`Model::from_product`]).
    pub const HDL32E: ProductId = ProductId(0x21);
    /// VLP-16.
    pub const VLP16: ProductId = ProductId(0x22);
    /// Puck Lite (same geometry as VLP-16).
    pub const PUCK_LITE: ProductId = ProductId(0x22);
    /// Puck Hi-Res.
    pub const PUCK_HIRES: ProductId = ProductId(0x24);
    /// VLP-32C.
    pub const VLP32C: ProductId = ProductId(0x28);
    /// Velarray (not supported).
    pub const VELARRAY: ProductId = ProductId(0x31);
    /// VLS-128 (not supported yet).
    pub const VLS128: ProductId = ProductId(0xA1);
}

/// How a laser's firing time and block position relate (per model).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// Duration of one firing sequence (all lasers once, plus recharge), in microseconds.
    pub sequence_us: f64,
    /// Time between consecutive firings within a sequence, in microseconds.
    pub firing_us: f64,
    /// Lasers that fire at the same instant (1, or 2 on the VLP-32C).
    pub simultaneous: usize,
    /// Firing sequences stored in one 32-channel block (2 for 16-laser models).
    pub sequences_per_block: usize,
}

/// Built-in geometry of one laser, as the manual gives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaserSpec {
    /// Elevation in degrees.
    pub vertical_deg: f64,
    /// Azimuth offset in degrees (positive: the beam points clockwise of the block azimuth, seen
    /// from above, i.e. the manual's sign).
    pub azimuth_offset_deg: f64,
    /// Vertical correction in metres, added to z (the manuals' definition).
    pub vertical_offset_m: f64,
}

const fn l(vertical_deg: f64, azimuth_offset_deg: f64, vertical_offset_mm: f64) -> LaserSpec {
    LaserSpec {
        vertical_deg,
        azimuth_offset_deg,
        vertical_offset_m: vertical_offset_mm / 1000.0,
    }
}

/// VLP-16 manual, table 9-1 (laser id order, i.e. firing order).
const VLP16: [LaserSpec; 16] = [
    l(-15.0, 0.0, 11.2),
    l(1.0, 0.0, -0.7),
    l(-13.0, 0.0, 9.7),
    l(3.0, 0.0, -2.2),
    l(-11.0, 0.0, 8.1),
    l(5.0, 0.0, -3.7),
    l(-9.0, 0.0, 6.6),
    l(7.0, 0.0, -5.1),
    l(-7.0, 0.0, 5.1),
    l(9.0, 0.0, -6.6),
    l(-5.0, 0.0, 3.7),
    l(11.0, 0.0, -8.1),
    l(-3.0, 0.0, 2.2),
    l(13.0, 0.0, -9.7),
    l(-1.0, 0.0, 0.7),
    l(15.0, 0.0, -11.2),
];

/// Puck Hi-Res manual, table 9-2.
const PUCK_HIRES: [LaserSpec; 16] = [
    l(-10.00, 0.0, 7.4),
    l(0.67, 0.0, -0.9),
    l(-8.67, 0.0, 6.5),
    l(2.00, 0.0, -1.8),
    l(-7.33, 0.0, 5.5),
    l(3.33, 0.0, -2.7),
    l(-6.00, 0.0, 4.6),
    l(4.67, 0.0, -3.7),
    l(-4.67, 0.0, 3.7),
    l(6.00, 0.0, -4.6),
    l(-3.33, 0.0, 2.7),
    l(7.33, 0.0, -5.5),
    l(-2.00, 0.0, 1.8),
    l(8.67, 0.0, -6.5),
    l(-0.67, 0.0, 0.9),
    l(10.00, 0.0, -7.4),
];

/// VLP-32C manual, table 9-1: elevation and azimuth offset per laser id.
const VLP32C: [LaserSpec; 32] = [
    l(-25.0, 1.4, 0.0),
    l(-1.0, -4.2, 0.0),
    l(-1.667, 1.4, 0.0),
    l(-15.639, -1.4, 0.0),
    l(-11.31, 1.4, 0.0),
    l(0.0, -1.4, 0.0),
    l(-0.667, 4.2, 0.0),
    l(-8.843, -1.4, 0.0),
    l(-7.254, 1.4, 0.0),
    l(0.333, -4.2, 0.0),
    l(-0.333, 1.4, 0.0),
    l(-6.148, -1.4, 0.0),
    l(-5.333, 4.2, 0.0),
    l(1.333, -1.4, 0.0),
    l(0.667, 4.2, 0.0),
    l(-4.0, -1.4, 0.0),
    l(-4.667, 1.4, 0.0),
    l(1.667, -4.2, 0.0),
    l(1.0, 1.4, 0.0),
    l(-3.667, -4.2, 0.0),
    l(-3.333, 4.2, 0.0),
    l(3.333, -1.4, 0.0),
    l(2.333, 1.4, 0.0),
    l(-2.667, -1.4, 0.0),
    l(-3.0, 1.4, 0.0),
    l(7.0, -1.4, 0.0),
    l(4.667, 1.4, 0.0),
    l(-2.333, -4.2, 0.0),
    l(-2.0, 4.2, 0.0),
    l(15.0, -1.4, 0.0),
    l(10.333, 1.4, 0.0),
    l(-1.333, -1.4, 0.0),
];

/// HDL-32E manual, appendix: elevation per laser id (lasers interleave low and high).
const HDL32E: [LaserSpec; 32] = [
    l(-30.67, 0.0, 0.0),
    l(-9.33, 0.0, 0.0),
    l(-29.33, 0.0, 0.0),
    l(-8.00, 0.0, 0.0),
    l(-28.00, 0.0, 0.0),
    l(-6.67, 0.0, 0.0),
    l(-26.67, 0.0, 0.0),
    l(-5.33, 0.0, 0.0),
    l(-25.33, 0.0, 0.0),
    l(-4.00, 0.0, 0.0),
    l(-24.00, 0.0, 0.0),
    l(-2.67, 0.0, 0.0),
    l(-22.67, 0.0, 0.0),
    l(-1.33, 0.0, 0.0),
    l(-21.33, 0.0, 0.0),
    l(0.00, 0.0, 0.0),
    l(-20.00, 0.0, 0.0),
    l(1.33, 0.0, 0.0),
    l(-18.67, 0.0, 0.0),
    l(2.67, 0.0, 0.0),
    l(-17.33, 0.0, 0.0),
    l(4.00, 0.0, 0.0),
    l(-16.00, 0.0, 0.0),
    l(5.33, 0.0, 0.0),
    l(-14.67, 0.0, 0.0),
    l(6.67, 0.0, 0.0),
    l(-13.33, 0.0, 0.0),
    l(8.00, 0.0, 0.0),
    l(-12.00, 0.0, 0.0),
    l(9.33, 0.0, 0.0),
    l(-10.67, 0.0, 0.0),
    l(10.67, 0.0, 0.0),
];

impl Model {
    /// Every supported model.
    pub const ALL: [Model; 4] = [Model::Vlp16, Model::PuckHiRes, Model::Vlp32c, Model::Hdl32e];

    /// The model a product byte names, if supported.
    ///
    /// Early VLP-16 firmware writes 0x21 (the HDL-32E byte): the caller should let the user force
    /// the model, and [`crate::decode::plausibility`] warns when the geometry does not fit.
    pub fn from_product(id: ProductId) -> Option<Model> {
        match id {
            ProductId::HDL32E => Some(Model::Hdl32e),
            ProductId::VLP16 => Some(Model::Vlp16),
            ProductId::PUCK_HIRES => Some(Model::PuckHiRes),
            ProductId::VLP32C => Some(Model::Vlp32c),
            _ => None,
        }
    }

    /// The product byte this model writes.
    pub fn product(self) -> ProductId {
        match self {
            Model::Vlp16 => ProductId::VLP16,
            Model::PuckHiRes => ProductId::PUCK_HIRES,
            Model::Vlp32c => ProductId::VLP32C,
            Model::Hdl32e => ProductId::HDL32E,
        }
    }

    /// Number of lasers.
    pub fn lasers(self) -> usize {
        self.laser_specs().len()
    }

    /// Built-in geometry per laser id.
    pub fn laser_specs(self) -> &'static [LaserSpec] {
        match self {
            Model::Vlp16 => &VLP16,
            Model::PuckHiRes => &PUCK_HIRES,
            Model::Vlp32c => &VLP32C,
            Model::Hdl32e => &HDL32E,
        }
    }

    /// Metres per distance count: 2 mm, except the VLP-32C's 4 mm.
    pub fn distance_resolution_m(self) -> f64 {
        match self {
            Model::Vlp32c => 0.004,
            _ => 0.002,
        }
    }

    /// The firing cycle.
    pub fn timing(self) -> Timing {
        match self {
            Model::Vlp16 | Model::PuckHiRes => Timing {
                sequence_us: 55.296,
                firing_us: 2.304,
                simultaneous: 1,
                sequences_per_block: 2,
            },
            Model::Vlp32c => Timing {
                sequence_us: 55.296,
                firing_us: 2.304,
                simultaneous: 2,
                sequences_per_block: 1,
            },
            Model::Hdl32e => Timing {
                sequence_us: 46.080,
                firing_us: 1.152,
                simultaneous: 1,
                sequences_per_block: 1,
            },
        }
    }

    /// Nominal maximum range in metres (specification sheet).
    pub fn max_range_m(self) -> f64 {
        match self {
            Model::Vlp32c => 200.0,
            Model::Hdl32e => 100.0,
            Model::Vlp16 | Model::PuckHiRes => 100.0,
        }
    }

    /// Short lower-case name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Model::Vlp16 => "vlp16",
            Model::PuckHiRes => "puck-hires",
            Model::Vlp32c => "vlp32c",
            Model::Hdl32e => "hdl32e",
        }
    }
}

impl fmt::Display for Model {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Model {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let norm: String = s
            .chars()
            .filter(|c| c.is_ascii_alphanumeric())
            .collect::<String>()
            .to_ascii_lowercase();
        match norm.as_str() {
            "vlp16" | "puck" | "pucklite" => Ok(Model::Vlp16),
            "puckhires" | "vlp16hires" => Ok(Model::PuckHiRes),
            "vlp32c" | "ultrapuck" => Ok(Model::Vlp32c),
            "hdl32e" | "hdl32" => Ok(Model::Hdl32e),
            _ => Err(format!(
                "unknown Velodyne model '{s}': expected one of vlp16, puck-hires, vlp32c, hdl32e"
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back() {
        for m in Model::ALL {
            assert_eq!(m.name().parse::<Model>(), Ok(m));
            assert_eq!(Model::from_product(m.product()), Some(m));
        }
        assert!("hdl64".parse::<Model>().is_err());
    }

    #[test]
    fn tables_are_complete_and_distinct() {
        for m in Model::ALL {
            let mut v: Vec<f64> = m.laser_specs().iter().map(|s| s.vertical_deg).collect();
            v.sort_by(f64::total_cmp);
            v.dedup();
            assert_eq!(v.len(), m.lasers(), "{m}: vertical angles must be distinct");
        }
    }
}
