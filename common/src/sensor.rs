//! The ego sensor model: range, field of view, occlusion by footprints, noise and dropout.
