//! The sidelink (V2V / V2I) radio channel of 3GPP TR 37.885 ("Study on evaluation methodology
//! of new V2X use cases for LTE and NR"): median path loss by its Table 6.2.1-1 (and WINNER+ B1,
//! which the LTE-V2X study of [`super::sps_reference`] uses), log-normal shadowing, a link
//! budget, and reception when the signal-to-noise ratio reaches the threshold of the packet's
//! modulation and coding. The packet delivery ratio (PDR) at a distance is the probability, over
//! the shadowing, that it does.
//!
//! Not modelled here: interference from other transmitters and half-duplex losses (both lower
//! the PDR at range; [`super::sps`] simulates them), the NLOSv blockage by other vehicles, the
//! shadowing's correlation in space.

use serde::Serialize;

/// The shortest 3D distance the formulas are used at; shorter ones are clamped to it: they are
/// log-distance fits for vehicles metres apart, not for the near field (ns-3 applies no clamp).
pub const MIN_DISTANCE_M: f64 = 3.0;

/// A path-loss model: those of TR 37.885 Table 6.2.1-1, and WINNER+ B1 line of sight.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum PathLoss {
    /// Highway, line of sight (also NLOSv before its blockage term).
    HighwayLos,
    /// Urban grid, line of sight.
    UrbanLos,
    /// Urban grid, buildings in the way.
    UrbanNlos,
    /// WINNER+ B1 line of sight (P. Kyösti et al., "WINNER II Channel Models", IST-4-027756
    /// WINNER II D1.1.2, 2008, scenario B1; kept in WINNER+ D5.3) between 1.5 m antennas on
    /// open ground, never below free space, as Gonzalez-Martín et al. 2019 evaluate LTE-V2X on
    /// a highway (their `get_PL_SH.m`, github.com/msepulcre/C-V2X).
    WinnerB1Los,
}

/// Antenna height above the ground of both vehicles for [`PathLoss::WinnerB1Los`], m.
const WINNER_B1_ANTENNA_HEIGHT_M: f64 = 1.5;

impl PathLoss {
    pub const ALL: [PathLoss; 4] =
        [PathLoss::HighwayLos, PathLoss::UrbanLos, PathLoss::UrbanNlos, PathLoss::WinnerB1Los];

    /// The model's name on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            PathLoss::HighwayLos => "3gpp-highway-los",
            PathLoss::UrbanLos => "3gpp-urban-los",
            PathLoss::UrbanNlos => "3gpp-urban-nlos",
            PathLoss::WinnerB1Los => "winner-b1-los",
        }
    }

    pub fn from_name(name: &str) -> Option<PathLoss> {
        PathLoss::ALL.into_iter().find(|m| m.name() == name)
    }

    /// Median path loss in dB at `distance_m` (3D, clamped to [`MIN_DISTANCE_M`]) and carrier
    /// `carrier_ghz`, without shadowing. NaN for a NaN distance (never a packet delivered).
    pub fn median_db(self, distance_m: f64, carrier_ghz: f64) -> f64 {
        let d = if distance_m.is_nan() { distance_m } else { distance_m.max(MIN_DISTANCE_M) }.log10();
        let f = carrier_ghz.log10();
        match self {
            PathLoss::HighwayLos => 32.4 + 20.0 * d + 20.0 * f,
            PathLoss::UrbanLos => 38.77 + 16.7 * d + 18.2 * f,
            PathLoss::UrbanNlos => 36.85 + 30.0 * d + 18.9 * f,
            PathLoss::WinnerB1Los => winner_b1_los_db(d, f, carrier_ghz),
        }
    }

    /// Standard deviation of the log-normal shadowing, dB (Table 6.2.1-1).
    pub const fn shadowing_sigma_db(self) -> f64 {
        match self {
            PathLoss::HighwayLos | PathLoss::UrbanLos | PathLoss::WinnerB1Los => 3.0,
            PathLoss::UrbanNlos => 4.0,
        }
    }
}

/// WINNER+ B1 LOS at log10 of the distance `lg_d` and of the carrier `lg_f` (GHz): up to the
/// breakpoint 4 h h f / c, 22.7 log d + 27 + 20 log f; beyond it, 40 log d + 7.56 − 17.3 log h
/// − 17.3 log h + 2.7 log f; never less than free space, 20 log d + 46.4 + 20 log (f / 5).
fn winner_b1_los_db(lg_d: f64, lg_f: f64, carrier_ghz: f64) -> f64 {
    let h = WINNER_B1_ANTENNA_HEIGHT_M;
    // c as 3·10⁸ m/s, as the authors' get_PL_SH.m takes it.
    let breakpoint_m = 4.0 * h * h * carrier_ghz * 1e9 / 3e8;
    let b1 = if lg_d < breakpoint_m.log10() {
        22.7 * lg_d + 27.0 + 20.0 * lg_f
    } else {
        40.0 * lg_d + 7.56 - 2.0 * 17.3 * h.log10() + 2.7 * lg_f
    };
    let free_space = 20.0 * lg_d + 46.4 + 20.0 * (lg_f - 5f64.log10());
    b1.max(free_space)
}

/// Thermal noise density at 290 K, dBm/Hz.
const THERMAL_NOISE_DBM_PER_HZ: f64 = -174.0;

/// The link budget of a transmission and what its reception needs. The defaults are the
/// evaluation assumptions of TR 36.885 / TR 37.885 for sidelink at 5.9 GHz (23 dBm, 3 dBi
/// antennas, 9 dB receiver noise figure, a 10 MHz channel) for their usual 190-byte packet: its
/// threshold ([`LTE_V2X_190B_MCS7_SINR_DB`]) is a spectral efficiency over the resource blocks
/// the packet occupies, so the noise is counted over those ([`LTE_V2X_190B_MCS7_BANDWIDTH_HZ`]),
/// with the whole transmit power in them, as WiLabV2Xsim does.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LinkBudget {
    pub carrier_ghz: f64,
    pub tx_power_dbm: f64,
    pub tx_antenna_gain_dbi: f64,
    pub rx_antenna_gain_dbi: f64,
    pub noise_figure_db: f64,
    /// The bandwidth the packet occupies, over which noise is counted.
    pub bandwidth_hz: f64,
    /// The signal-to-noise ratio a packet needs to be received, dB.
    pub sinr_threshold_db: f64,
}

/// The minimum SINR of a 190-byte LTE-V2X packet at MCS 7 in 10 MHz (13 resource-block pairs by
/// TS 36.213 Table 7.1.7.2.1-1), by the Shannon abstraction with a 0.37 implementation loss of
/// Wu, Bartoletti, Martinez, Bazzi, "A Methodology for Abstracting the Physical Layer of Direct
/// V2X Communications Technologies", Sensors 22(23):9330, 2022 (as WiLabV2Xsim computes it):
/// 1520 b × 50 / 13 RB / 1 ms / 10 MHz = 0.585 b/s/Hz; / 0.37 = 1.580; 2^1.580 − 1 = 1.99 → 2.99 dB.
pub const LTE_V2X_190B_MCS7_SINR_DB: f64 = 2.99;

/// The 13 resource blocks of 180 kHz that packet occupies.
pub const LTE_V2X_190B_MCS7_BANDWIDTH_HZ: f64 = 13.0 * 180e3;

impl Default for LinkBudget {
    fn default() -> Self {
        LinkBudget {
            carrier_ghz: 5.9,
            tx_power_dbm: 23.0,
            tx_antenna_gain_dbi: 3.0,
            rx_antenna_gain_dbi: 3.0,
            noise_figure_db: 9.0,
            bandwidth_hz: LTE_V2X_190B_MCS7_BANDWIDTH_HZ,
            sinr_threshold_db: LTE_V2X_190B_MCS7_SINR_DB,
        }
    }
}

/// What the channel gives at one distance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ChannelPoint {
    pub distance_m: f64,
    /// Median path loss (no shadowing sample).
    pub path_loss_db: f64,
    pub shadowing_sigma_db: f64,
    /// Median signal-to-noise ratio.
    pub snr_db: f64,
    /// Delivery probability, shadowing included.
    pub pdr: f64,
}

impl LinkBudget {
    /// Why these numbers cannot make a link budget, if they cannot.
    pub fn check(&self) -> Result<(), String> {
        let finite = [
            ("tx_power_dbm", self.tx_power_dbm),
            ("tx_antenna_gain_dbi", self.tx_antenna_gain_dbi),
            ("rx_antenna_gain_dbi", self.rx_antenna_gain_dbi),
            ("noise_figure_db", self.noise_figure_db),
            ("sinr_threshold_db", self.sinr_threshold_db),
        ];
        if let Some((name, v)) = finite.into_iter().find(|(_, v)| !v.is_finite()) {
            return Err(format!("{name} {v} is not a number"));
        }
        // The span of 3GPP's channel models (TR 38.901: 0.5–100 GHz; sidelink uses 5.9 and 63 GHz).
        if !(0.5..=100.0).contains(&self.carrier_ghz) {
            return Err(format!("carrier {} GHz is outside the models' 0.5–100 GHz", self.carrier_ghz));
        }
        if !(self.bandwidth_hz.is_finite() && self.bandwidth_hz > 0.0) {
            return Err(format!("bandwidth {} Hz must be positive", self.bandwidth_hz));
        }
        if self.noise_figure_db < 0.0 {
            return Err(format!("noise figure {} dB cannot be negative", self.noise_figure_db));
        }
        Ok(())
    }

    /// Noise power over the channel at the receiver, dBm.
    pub fn noise_dbm(&self) -> f64 {
        THERMAL_NOISE_DBM_PER_HZ + 10.0 * self.bandwidth_hz.log10() + self.noise_figure_db
    }

    /// The median signal-to-noise ratio at path loss `path_loss_db`, dB.
    pub fn snr_db(&self, path_loss_db: f64) -> f64 {
        self.tx_power_dbm + self.tx_antenna_gain_dbi + self.rx_antenna_gain_dbi - path_loss_db - self.noise_dbm()
    }

    /// The channel of `model` at `distance_m` (a finite distance ≥ 0).
    pub fn at(&self, model: PathLoss, distance_m: f64) -> ChannelPoint {
        let path_loss_db = model.median_db(distance_m, self.carrier_ghz);
        let snr_db = self.snr_db(path_loss_db);
        let sigma = model.shadowing_sigma_db();
        // Received when the shadowing X ~ N(0, σ) added to the loss leaves the SNR at the
        // threshold or above: X ≤ snr − threshold.
        let pdr = normal_cdf((snr_db - self.sinr_threshold_db) / sigma);
        ChannelPoint { distance_m, path_loss_db, shadowing_sigma_db: sigma, snr_db, pdr }
    }
}

/// The standard normal distribution function Φ(z).
pub fn normal_cdf(z: f64) -> f64 {
    0.5 * libm::erfc(-z / std::f64::consts::SQRT_2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn path_loss_is_table_6_2_1_1_at_several_distances() {
        // Worked by hand at 5.9 GHz: log10(5.9) = 0.770852.
        let lg = 5.9f64.log10();
        for d in [3.0f64, 10.0, 50.0, 100.0, 320.0, 1000.0] {
            let l = d.log10();
            let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
            assert!(close(PathLoss::HighwayLos.median_db(d, 5.9), 32.4 + 20.0 * l + 20.0 * lg));
            assert!(close(PathLoss::UrbanLos.median_db(d, 5.9), 38.77 + 16.7 * l + 18.2 * lg));
            assert!(close(PathLoss::UrbanNlos.median_db(d, 5.9), 36.85 + 30.0 * l + 18.9 * lg));
        }
        // 100 m on a highway: 32.4 + 40 + 15.417 = 87.817 dB.
        assert!((PathLoss::HighwayLos.median_db(100.0, 5.9) - 87.817).abs() < 1e-3);
        // Below 3 m the model holds its 3 m value.
        assert_eq!(PathLoss::UrbanLos.median_db(0.5, 5.9), PathLoss::UrbanLos.median_db(3.0, 5.9));
        assert_eq!(PathLoss::UrbanNlos.shadowing_sigma_db(), 4.0);
    }

    #[test]
    fn winner_b1_is_the_published_models_at_several_distances() {
        // The authors' get_PL_SH.m (github.com/msepulcre/C-V2X, 71d4c25) run in GNU Octave 7.3 at
        // 5.91 GHz: free space up to ~100 m, B1 below the 177 m breakpoint, the 40 log d branch
        // beyond it, 3 m held below 3 m.
        let octave = [
            (2.0, 57.394_774_625),
            (50.0, 81.831_749_618),
            (150.0, 91.829_021_198),
            (177.0, 93.460_742_764),
            (178.0, 93.567_328_727),
            (300.0, 102.635_378_824),
            (500.0, 111.509_328_808),
            (1000.0, 123.550_528_635),
        ];
        for (d, want) in octave {
            let got = PathLoss::WinnerB1Los.median_db(d, 5.91);
            assert!((got - want).abs() < 1e-6, "{d} m: {got} against {want}");
        }
        assert!(PathLoss::WinnerB1Los.median_db(f64::NAN, 5.91).is_nan());
        assert_eq!(PathLoss::from_name("winner-b1-los"), Some(PathLoss::WinnerB1Los));
    }

    #[test]
    fn the_default_budget_has_the_evaluation_noise_and_pdr_falls_with_distance() {
        let budget = LinkBudget::default();
        // −174 dBm/Hz over 2.34 MHz (63.69 dB) with a 9 dB noise figure.
        assert!((budget.noise_dbm() - (-101.308)).abs() < 1e-3, "{}", budget.noise_dbm());
        let lg = 5.9f64.log10();
        for (model, a, b, c) in [
            (PathLoss::HighwayLos, 32.4, 20.0, 20.0),
            (PathLoss::UrbanLos, 38.77, 16.7, 18.2),
            (PathLoss::UrbanNlos, 36.85, 30.0, 18.9),
        ] {
            // Where the median SNR is the threshold, half the packets arrive; a third as far,
            // nearly all; three times as far, nearly none.
            let edge_loss = 23.0 + 6.0 - budget.noise_dbm() - LTE_V2X_190B_MCS7_SINR_DB;
            let edge_m = 10f64.powf((edge_loss - a - c * lg) / b);
            let pdr = |d: f64| budget.at(model, d).pdr;
            assert!((pdr(edge_m) - 0.5).abs() < 1e-9, "{model:?}: {edge_m} m");
            assert!(pdr(edge_m / 3.0) > 0.99 && pdr(3.0 * edge_m) < 0.01, "{model:?} around {edge_m} m");
            let falling: Vec<f64> = (1..40).map(|k| pdr(edge_m * k as f64 / 10.0)).collect();
            assert!(falling.windows(2).all(|w| w[1] < w[0]), "{model:?}: {falling:?}");
        }
        assert!(budget.at(PathLoss::UrbanLos, f64::NAN).pdr.is_nan(), "a NaN distance is never a delivery");
    }

    #[test]
    fn normal_cdf_matches_known_values() {
        for (z, p) in [(0.0, 0.5), (1.0, 0.841_344_746), (-1.959_963_985, 0.025), (3.0, 0.998_650_102)] {
            assert!((normal_cdf(z) - p).abs() < 1e-9, "{z}: {}", normal_cdf(z));
        }
    }

    #[test]
    fn impossible_budgets_are_refused_by_name() {
        let bad = [
            LinkBudget { carrier_ghz: 0.0, ..LinkBudget::default() },
            LinkBudget { bandwidth_hz: -1.0, ..LinkBudget::default() },
            LinkBudget { tx_power_dbm: f64::NAN, ..LinkBudget::default() },
            LinkBudget { noise_figure_db: -3.0, ..LinkBudget::default() },
        ];
        for (budget, word) in bad.iter().zip(["carrier", "bandwidth", "tx_power_dbm", "noise figure"]) {
            let e = budget.check().expect_err("refused");
            assert!(e.contains(word), "{e}");
        }
        assert_eq!(LinkBudget::default().check(), Ok(()));
    }
}
