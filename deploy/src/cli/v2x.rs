//! `risktwin v2x …`: the V2X radio channel.

use crate::output::Format;
use clap::{Args, Subcommand};

#[derive(Debug, Subcommand)]
pub enum V2xCommand {
    /// Path loss, SNR and packet delivery ratio of a 3GPP TR 37.885 sidelink channel by distance.
    Channel(V2xChannelArgs),
    /// A grid of channels, latencies, losses and warning rates over critical scenes of every
    /// kind, in virtual time: the twin's staleness and the crashes warnings prevent (docs/v2x.md).
    Sweep(V2xSweepArgs),
}

#[derive(Debug, Args)]
pub struct V2xSweepArgs {
    /// JSON file with any of the grid's keys (docs/v2x.md); without it, the default grid.
    #[arg(long)]
    pub config: Option<std::path::PathBuf>,
    /// Folder for the report, figures and CSV files (created; files in it are replaced).
    #[arg(long)]
    pub out: std::path::PathBuf,
}

#[derive(Debug, Args)]
pub struct V2xChannelArgs {
    /// 3gpp-highway-los, 3gpp-urban-los, 3gpp-urban-nlos or winner-b1-los.
    #[arg(long)]
    pub model: String,
    /// Distances between the antennas, m (comma-separated; below 3 m the model holds its 3 m value).
    #[arg(long, value_delimiter = ',', required = true, allow_negative_numbers = true)]
    pub distance_m: Vec<f64>,
    /// Carrier, GHz (default 5.9).
    #[arg(long, allow_negative_numbers = true)]
    pub carrier_ghz: Option<f64>,
    /// Transmit power, dBm (default 23).
    #[arg(long, allow_negative_numbers = true)]
    pub tx_power_dbm: Option<f64>,
    /// Gain of each antenna (transmitter and receiver), dBi (default 3).
    #[arg(long, allow_negative_numbers = true)]
    pub antenna_gain_dbi: Option<f64>,
    /// Receiver noise figure, dB (default 9).
    #[arg(long, allow_negative_numbers = true)]
    pub noise_figure_db: Option<f64>,
    /// Bandwidth the packet occupies, over which noise is counted, MHz (default 2.34: the 13
    /// resource blocks of a 190-byte LTE-V2X packet at MCS 7).
    #[arg(long, allow_negative_numbers = true)]
    pub bandwidth_mhz: Option<f64>,
    /// SNR a packet needs, dB (default 2.99: that packet's; see docs/v2x.md).
    #[arg(long, allow_negative_numbers = true)]
    pub sinr_threshold_db: Option<f64>,
    #[arg(long, value_enum, default_value_t = Format::Table)]
    pub format: Format,
}
