//! Reference data (Rosenberger et al. 2019, §3-§8): the ego trajectory from RTK GNSS and CAN, and `check`, the
//! validator that judges spatial and temporal accuracy before anything is re-simulated.

pub mod check;
pub mod noise;
pub mod run;
pub mod trajectory;
