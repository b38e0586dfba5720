//! Emulated deployments (issue 15, in progress): links emulated in user space ([`relay`]).

pub mod relay;
