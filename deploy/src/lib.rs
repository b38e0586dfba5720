//! The parts of the `risktwin` binary that are reachable from outside it: the deployment
//! topology parser, which the binary uses (`risktwin deploy`) and the fuzz targets in `fuzz/`
//! call directly. Everything else of the binary stays private to it.

pub mod topology;
