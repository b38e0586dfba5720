//! Block error rate against SINR: the link-level curve a system-level model reads to decide
//! whether one packet is decoded, instead of a hard SINR threshold. A curve is a table of points,
//! linear between them in BLER against SINR in dB, flat beyond its ends.

use serde::Serialize;

/// A BLER-against-SINR curve: points with rising SINR.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BlerCurve {
    /// (SINR in dB, BLER) in rising SINR.
    pub points: &'static [(f64, f64)],
}

/// A 190-byte LTE-V2X packet, QPSK at code rate 0.7 over 10 resource blocks, 280 km/h relative
/// speed: 3GPP R1-160284 ("DMRS enhancement of V2V", RAN1 #84), as Gonzalez-Martín et al.
/// (IEEE TVT 68(2), 2019) tabulate it in their `get_BLER.m` (curve 1, github.com/msepulcre/C-V2X):
/// every packet lost below 0 dB, 1e-4 of them above 20 dB.
pub const LTE_V2X_190B_QPSK_R07: BlerCurve = BlerCurve {
    points: &[
        (0.0, 1.0),
        (2.0, 0.9),
        (4.0, 0.7),
        (6.0, 0.4),
        (8.0, 0.13),
        (10.0, 0.045),
        (12.0, 0.017),
        (14.0, 0.007),
        (16.0, 1e-3),
        (18.0, 1e-3),
        (20.0, 1e-3),
        (20.000_001, 1e-4),
    ],
};

impl BlerCurve {
    /// The share of packets lost at `sinr_db`; the end values outside the table, 1 for NaN.
    pub fn at(&self, sinr_db: f64) -> f64 {
        let points = self.points;
        let (Some(&(lo_db, lo_bler)), Some(&(hi_db, hi_bler))) = (points.first(), points.last()) else {
            return 1.0;
        };
        if sinr_db.is_nan() {
            return 1.0;
        }
        if sinr_db <= lo_db {
            return lo_bler;
        }
        if sinr_db >= hi_db {
            return hi_bler;
        }
        // The first point at or above sinr_db; the one before it is below.
        let i = points.partition_point(|&(db, _)| db < sinr_db);
        let ((x0, y0), (x1, y1)) = (points[i - 1], points[i]);
        y0 + (y1 - y0) * (sinr_db - x0) / (x1 - x0)
    }

    /// Why this table cannot be a curve, if it cannot.
    pub fn check(&self) -> Result<(), String> {
        if self.points.is_empty() {
            return Err("a BLER curve needs at least one point".into());
        }
        if let Some((db, bler)) = self.points.iter().find(|(db, b)| !(db.is_finite() && (0.0..=1.0).contains(b))) {
            return Err(format!("BLER point ({db} dB, {bler}): need a finite SINR and a BLER in [0, 1]"));
        }
        if let Some(w) = self.points.windows(2).find(|w| w[1].0 <= w[0].0) {
            return Err(format!("BLER points at {} dB then {} dB: SINR must rise", w[0].0, w[1].0));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_curve_is_its_points_linear_between_and_flat_beyond() {
        let c = LTE_V2X_190B_QPSK_R07;
        assert_eq!(c.check(), Ok(()));
        for &(db, bler) in c.points {
            assert!((c.at(db) - bler).abs() < 1e-12, "{db} dB");
        }
        // Halfway between 6 dB (0.4) and 8 dB (0.13).
        assert!((c.at(7.0) - 0.265).abs() < 1e-12);
        assert_eq!(c.at(-5.0), 1.0);
        assert_eq!(c.at(30.0), 1e-4);
        assert_eq!(c.at(f64::NAN), 1.0);
        let falling: Vec<f64> = (0..=44).map(|k| c.at(k as f64 * 0.5)).collect();
        assert!(falling.windows(2).all(|w| w[1] <= w[0]), "{falling:?}");
    }

    #[test]
    fn bad_tables_are_refused() {
        let bad = [
            BlerCurve { points: &[] },
            BlerCurve { points: &[(0.0, 1.5)] },
            BlerCurve { points: &[(2.0, 0.5), (1.0, 0.1)] },
        ];
        for (curve, word) in bad.iter().zip(["at least one", "BLER in [0, 1]", "must rise"]) {
            let e = curve.check().expect_err("refused");
            assert!(e.contains(word), "{e}");
        }
    }
}
