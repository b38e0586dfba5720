//! Ego vehicle dynamics: parameters, kinematic and dynamic single-track models, actuators.
