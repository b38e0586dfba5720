//! Edge roles (vehicle, RSU, replay) land with the edge–cloud pipeline; nothing here yet.
