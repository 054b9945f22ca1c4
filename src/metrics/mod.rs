//! Metrics between a measured run and its re-simulation (Rosenberger et al. 2019, §5): grid
//! metrics ([`grid`]: OCR^K, precision, IoU, cosine), point metrics ([`points`]: Chamfer,
//! Hausdorff), regions of interest ([`roi`]) and the scan-by-scan comparison that `hilrig
//! compare` runs ([`compare`], on a run [`checked`] once) on the scans [`pairing`] pairs as both files stream by: each pair measured by
//! itself ([`measure`]), the grids of windows of K scans ([`windows`]), what it reports
//! ([`report`]) and the bird's-eye view of one scan pair ([`snapshot`]), and the running results of the pass ([`tally`]).

mod checked;
mod cloud;
pub mod compare;
mod error;
pub mod features;
pub mod grid;
mod measure;
mod pairing;
pub mod points;
pub mod report;
pub mod roi;
mod snapshot;
mod tally;
mod windows;
