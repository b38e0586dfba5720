//! `risktwin v2x …`: the V2X radio channel.

use crate::output::Format;
use clap::{Args, Subcommand};

#[derive(Debug, Subcommand)]
pub enum V2xCommand {
    /// Path loss, SNR and packet delivery ratio of a 3GPP TR 37.885 sidelink channel by distance.
    Channel(V2xChannelArgs),
}

#[derive(Debug, Args)]
pub struct V2xChannelArgs {
    /// 3gpp-highway-los, 3gpp-urban-los or 3gpp-urban-nlos.
    #[arg(long)]
    pub model: String,
    /// Distances between the antennas, m (comma-separated; below 3 m the model holds its 3 m value).
    #[arg(long, value_delimiter = ',', required = true, allow_negative_numbers = true)]
    pub distance_m: Vec<f64>,
    #[arg(long, default_value_t = 5.9, allow_negative_numbers = true)]
    pub carrier_ghz: f64,
    #[arg(long, default_value_t = 23.0, allow_negative_numbers = true)]
    pub tx_power_dbm: f64,
    /// Gain of each antenna (transmitter and receiver), dBi.
    #[arg(long, default_value_t = 3.0, allow_negative_numbers = true)]
    pub antenna_gain_dbi: f64,
    #[arg(long, default_value_t = 9.0, allow_negative_numbers = true)]
    pub noise_figure_db: f64,
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    pub bandwidth_mhz: f64,
    /// SNR a packet needs, dB (default: a 190-byte LTE-V2X packet at MCS 7; see docs/v2x.md).
    #[arg(long, allow_negative_numbers = true)]
    pub sinr_threshold_db: Option<f64>,
    #[arg(long, value_enum, default_value_t = Format::Table)]
    pub format: Format,
}
