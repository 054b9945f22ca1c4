//! Statistics over repetitions (Rosenberger et al. 2019, §8): the area validation metric and the
//! traffic-light comparison of real and simulated metric ranges (Fig. 7); and for choosing
//! scenarios (§4), the eFAST sensitivity of a metric to scenario parameters. (The estimators
//! that `metrics` shares, such as the rank correlation of Fig. 5, are in [`crate::estimate`].)

pub mod avm;
pub mod coverage;
pub mod efast;
pub mod repetitions;
pub mod scenario;
pub mod validate;
