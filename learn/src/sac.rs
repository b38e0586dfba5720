//! SAC: to come.
