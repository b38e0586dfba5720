//! The wire schema (`proto/risktwin/v1/*.proto`) and its conversions land with the edge–cloud pipeline; nothing here yet.
