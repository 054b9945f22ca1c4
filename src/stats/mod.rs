//! Statistics over repetitions (Rosenberger et al. 2019, §8): the area validation metric, the
//! traffic-light comparison of real and simulated metric ranges (Fig. 7), and rank correlation
//! with a bootstrap interval (the Fig. 5 trend of a metric against distance); and for choosing
//! scenarios (§4), the eFAST sensitivity of a metric to scenario parameters.

pub mod avm;
pub mod coverage;
pub mod efast;
pub mod rank;
pub mod repetitions;
pub mod scenario;
pub mod validate;
