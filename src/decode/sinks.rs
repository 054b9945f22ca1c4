//! Writers for decoded points: CSV and JSON lines.
//!
//! The CSV header is fixed (`time_s,ring,azimuth_deg,distance_m,intensity,return_type,x,y,z`) so
//! scripts can rely on it. Times are written exactly (`seconds.nanoseconds`, from integers) rather
//! than through a float, which would lose sub-microsecond digits at Unix-epoch magnitudes.

use crate::decode::lidar::{point_time, PointSink, PointTime};
use hilrig_velodyne::Point;
use std::io::{self, Write};

/// The CSV header line.
pub const CSV_HEADER: &str = "time_s,ring,azimuth_deg,distance_m,intensity,return_type,x,y,z";

/// Writes one CSV row per point.
pub struct CsvSink<W: Write> {
    out: W,
}

impl<W: Write> CsvSink<W> {
    /// Writes the header.
    pub fn new(mut out: W) -> io::Result<Self> {
        writeln!(out, "{CSV_HEADER}")?;
        Ok(CsvSink { out })
    }

    /// Flushes and returns the writer.
    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

impl<W: Write> PointSink for CsvSink<W> {
    fn packet(&mut self, packet_time: PointTime, points: &[Point]) -> io::Result<()> {
        for p in points {
            writeln!(
                self.out,
                "{},{},{:.3},{:.3},{},{},{:.4},{:.4},{:.4}",
                point_time(packet_time, p).to_seconds_string(),
                p.ring,
                p.azimuth_deg,
                p.distance_m,
                p.intensity,
                p.return_type as u8,
                p.x,
                p.y,
                p.z
            )?;
        }
        Ok(())
    }
}

/// Writes one JSON object per point, with the same fields as the CSV plus the laser id.
pub struct JsonlSink<W: Write> {
    out: W,
}

impl<W: Write> JsonlSink<W> {
    /// A sink on a writer.
    pub fn new(out: W) -> Self {
        JsonlSink { out }
    }

    /// Flushes and returns the writer.
    pub fn finish(mut self) -> io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

impl<W: Write> PointSink for JsonlSink<W> {
    fn packet(&mut self, packet_time: PointTime, points: &[Point]) -> io::Result<()> {
        for p in points {
            writeln!(
                self.out,
                "{{\"time_s\":{},\"ring\":{},\"laser\":{},\"azimuth_deg\":{:.3},\"distance_m\":{:.3},\"intensity\":{},\"return_type\":{},\"x\":{:.4},\"y\":{:.4},\"z\":{:.4}}}",
                point_time(packet_time, p).to_seconds_string(),
                p.ring,
                p.laser.0,
                p.azimuth_deg,
                p.distance_m,
                p.intensity,
                p.return_type as u8,
                p.x,
                p.y,
                p.z
            )?;
        }
        Ok(())
    }
}
