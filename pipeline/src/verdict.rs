//! What the numbers show, computed rather than written by hand: the issue's target ("on the
//! held-out set, across ≥ 3 seeds, full has a lower collision rate than base at equal or better
//! route completion and average speed") checked against the ablation, and said in sentences,
//! including where full does not win.
//!
//! The rule is fixed here, before any result: "lower" compares means over seeds; "equal or
//! better" allows full to fall short of base by at most a fixed tolerance per metric
//! ([`COMPLETION_TOLERANCE`], [`SPEED_TOLERANCE_MPS`]) — not by the seeds' spread, which would
//! let a noisy comparison pass. A collision difference no larger than one seed standard
//! deviation (the larger of the two variants') is reported as within seed noise.

use risktwin_cloud::trainer::{AblationReport, EvalSpread, Spread};
use risktwin_common::env::Variant;
use risktwin_common::scenario::ScenarioKind;
use serde::Serialize;

/// Full against base on one kind.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KindComparison {
    pub kind: ScenarioKind,
    pub full_collision_rate: f64,
    pub base_collision_rate: f64,
    pub full_lower: bool,
}

/// The target, checked.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Verdict {
    pub seeds: usize,
    pub collision_lower: bool,
    /// The collision difference exceeds one seed standard deviation.
    pub collision_beyond_noise: bool,
    pub completion_equal_or_better: bool,
    pub speed_equal_or_better: bool,
    pub target_met: bool,
    /// Every learned variant at or below the reference driver's collision rate and at or above
    /// its success rate.
    pub every_variant_beats_reference: bool,
    pub by_kind: Vec<KindComparison>,
    /// The findings as sentences (also in report.md).
    pub sentences: Vec<String>,
}

/// Route completion full may lose against base and still count as equal (a share of the route).
pub const COMPLETION_TOLERANCE: f64 = 0.02;
/// Average speed full may lose against base and still count as equal, m/s.
pub const SPEED_TOLERANCE_MPS: f64 = 0.5;

fn within(full: &Spread, base: &Spread, tolerance: f64) -> bool {
    full.mean >= base.mean - tolerance
}

fn pm(s: &Spread) -> String {
    format!("{:.3} ± {:.3}", s.mean, s.std)
}

/// Compares full with base (and risk-only with both); `None` when either was not trained.
pub fn judge(ab: &AblationReport) -> Option<Verdict> {
    let (full, base) = (ab.variant(Variant::Full)?, ab.variant(Variant::Base)?);
    let seeds = full.seeds.len().min(base.seeds.len());
    let (f, b) = (&full.overall, &base.overall);
    let collision_lower = f.collision_rate.mean < b.collision_rate.mean;
    let noise = f.collision_rate.std.max(b.collision_rate.std);
    let collision_beyond_noise = (f.collision_rate.mean - b.collision_rate.mean).abs() > noise;
    let completion_equal_or_better = within(&f.route_completion, &b.route_completion, COMPLETION_TOLERANCE);
    let speed_equal_or_better = within(&f.avg_speed_mps, &b.avg_speed_mps, SPEED_TOLERANCE_MPS);
    let target_met = seeds >= 3 && collision_lower && completion_equal_or_better && speed_equal_or_better;
    let by_kind: Vec<KindComparison> = ScenarioKind::ALL
        .iter()
        .filter_map(|k| {
            let (fk, bk) = (full.by_kind.get(k)?, base.by_kind.get(k)?);
            Some(KindComparison {
                kind: *k,
                full_collision_rate: fk.collision_rate.mean,
                base_collision_rate: bk.collision_rate.mean,
                full_lower: fk.collision_rate.mean < bk.collision_rate.mean,
            })
        })
        .collect();

    let mut s = Vec::new();
    s.push(format!(
        "Target {}: on the held-out set ({} episodes, {seeds} seeds) full's collision rate is {} against base's {} \
         ({}{}), at route completion {} vs {} ({}) and average speed {} vs {} m/s ({}).",
        if target_met { "met" } else { "not met" },
        ab.held_out_episodes,
        pm(&f.collision_rate),
        pm(&b.collision_rate),
        if collision_lower {
            "lower"
        } else if f.collision_rate.mean == b.collision_rate.mean {
            "equal"
        } else {
            "higher"
        },
        if collision_beyond_noise { "" } else { ", within one seed standard deviation" },
        pm(&f.route_completion),
        pm(&b.route_completion),
        if completion_equal_or_better { "equal or better" } else { "worse" },
        pm(&f.avg_speed_mps),
        pm(&b.avg_speed_mps),
        if speed_equal_or_better { "equal or better" } else { "slower" },
    ));
    if seeds < 3 {
        s.push(format!("Only {seeds} seed(s) were trained; the target asks for at least three."));
    }
    let wins: Vec<String> = by_kind.iter().filter(|k| k.full_lower).map(|k| k.kind.to_string()).collect();
    let losses: Vec<String> = by_kind
        .iter()
        .filter(|k| k.full_collision_rate > k.base_collision_rate)
        .map(|k| format!("{} ({:.2} vs {:.2})", k.kind, k.full_collision_rate, k.base_collision_rate))
        .collect();
    s.push(format!(
        "By kind, full collides less than base on {} and more on {}.",
        if wins.is_empty() { "no kind".to_string() } else { wins.join(", ") },
        if losses.is_empty() { "no kind".to_string() } else { losses.join(", ") }
    ));
    let ended = |e: &EvalSpread| {
        format!(
            "{:.2} success, {:.2} collision, {:.2} off the road, {:.2} out of time",
            e.success_rate.mean, e.collision_rate.mean, e.offroad_rate.mean, e.timeout_rate.mean
        )
    };
    // Where full's avoided crashes went: the non-collision failures it has more of than base.
    let mut more = Vec::new();
    if f.offroad_rate.mean > b.offroad_rate.mean {
        more.push(format!("off the road ({:.2} vs {:.2})", f.offroad_rate.mean, b.offroad_rate.mean));
    }
    if f.timeout_rate.mean > b.timeout_rate.mean {
        more.push(format!(
            "out of time short of the route's end ({:.2} vs {:.2})",
            f.timeout_rate.mean, b.timeout_rate.mean
        ));
    }
    let trade = if f.collision_rate.mean < b.collision_rate.mean && !completion_equal_or_better && !more.is_empty() {
        let slow = if more.len() == 1 && f.timeout_rate.mean > b.timeout_rate.mean {
            ": it drives too slowly rather than unsafely"
        } else {
            ""
        };
        format!(" Full trades crashes for episodes that end {}{slow}.", more.join(" and "))
    } else {
        String::new()
    };
    s.push(format!("How the held-out episodes ended — full: {}; base: {}.{trade}", ended(f), ended(b)));
    if let Some(r) = ab.variant(Variant::RiskOnly) {
        let rc = r.overall.collision_rate.mean;
        s.push(format!(
            "Separating the two ingredients: the risk reward alone (risk-only) gives collision rate {rc:.3} against \
             base's {:.3}; adding the library scenarios (full) gives {:.3} against risk-only's {rc:.3}.",
            b.collision_rate.mean, f.collision_rate.mean
        ));
    }
    // The second target: every learned variant at or below the reference driver's
    // collision rate and at or above its success rate (means over seeds).
    let reference = &ab.reference.overall;
    let short: Vec<String> = ab
        .variants
        .iter()
        .filter(|v| {
            v.overall.collision_rate.mean > reference.collision_rate
                || v.overall.success_rate.mean < reference.success_rate
        })
        .map(|v| {
            format!(
                "{} ({:.3} collision, {:.3} success)",
                v.variant, v.overall.collision_rate.mean, v.overall.success_rate.mean
            )
        })
        .collect();
    // Never vacuous: `judge` has returned already unless base and full were trained.
    let every_variant_beats_reference = short.is_empty();
    s.push(if every_variant_beats_reference {
        format!(
            "Every learned variant collides at most as often as the reference driver ({:.3}) and succeeds at least as \
             often ({:.3}).",
            reference.collision_rate, reference.success_rate
        )
    } else {
        format!(
            "Against the reference driver ({:.3} collision, {:.3} success), short on collision or success: {}.",
            reference.collision_rate,
            reference.success_rate,
            short.join(", ")
        )
    });
    let best_success = ab.variants.iter().map(|v| v.overall.success_rate.mean).fold(0.0, f64::max);
    if best_success < 0.5 * reference.success_rate {
        s.push(format!(
            "Caveat: no learned policy drives well yet — the best success rate is {best_success:.2} against the \
             reference driver's {:.2} (collision {:.2}, route completion {:.2}) on the same scenarios, after {} \
             environment steps per run; differences between variants at this stage say more about how each \
             fails than about safe driving.",
            reference.success_rate, reference.collision_rate, reference.route_completion, ab.steps_per_run
        ));
    }
    Some(Verdict {
        seeds,
        collision_lower,
        collision_beyond_noise,
        completion_equal_or_better,
        speed_equal_or_better,
        target_met,
        every_variant_beats_reference,
        by_kind,
        sentences: s,
    })
}
