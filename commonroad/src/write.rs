//! [`Scenario`] → CommonRoad XML that [`super::parse_scenario`] reads back equal.
//!
//! Elements are written by a small helper (`Xml` below) rather than a crate: Cargo.lock has no XML
//! writer (roxmltree only reads), and the format needs nothing beyond nested elements,
//! attributes and escaped text.
//!
//! - What is written is what the parser reads. The model counts goal states without their
//!   regions, so each is an empty `<goalState/>`; location, traffic signs and lights and the
//!   header's author/date are not in the model and are not written.
//! - Numbers are written with `{}`: the shortest text that reads back to the same `f64` bits.
//! - Layout 2020a (`<dynamicObstacle>`, `<staticObstacle>`), or 2018b's `<obstacle>` with its
//!   `<role>` when the scenario's `version` is `2018b`: the version is written as it is (the
//!   parser reads it back), and it then names the obstacle layout truly.
//! - Deterministic: everything is written in model order.
//! - Not validated: a model the parser would refuse (non-finite numbers, gaps in a trajectory)
//!   is written as it is, and reading it back fails.

use super::model::{
    DynamicObstacle, Intersection, ObstacleState, PlacedShape, PlanningProblem, Scenario, Shape, StaticObstacle,
};
use crate::Lanelet;
use risktwin_common::geometry::Vec2;
use std::fmt::{Display, Write};

/// Writes `scenario` as an indented CommonRoad XML document.
///
/// A tag that is not an ASCII XML name (CommonRoad's tags all are) cannot be an element name
/// and is left out; characters XML 1.0 cannot carry at all (controls other than tab, line feed
/// and carriage return) are written as U+FFFD.
pub fn to_xml(scenario: &Scenario) -> String {
    let mut x = Xml { out: String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"), depth: 0 };
    let dt_s = scenario.dt_s.to_string();
    let root = [
        ("timeStepSize", dt_s.as_str()),
        ("commonRoadVersion", &scenario.version),
        ("benchmarkID", &scenario.benchmark_id),
    ];
    x.open("commonRoad", &root);
    let tags: Vec<&String> = scenario.tags.iter().filter(|t| is_ascii_name(t)).collect();
    if !tags.is_empty() {
        x.open("scenarioTags", &[]);
        for tag in tags {
            x.empty(tag, &[]);
        }
        x.close("scenarioTags");
    }
    for l in &scenario.lanelets.lanelets {
        lanelet(&mut x, l);
    }
    for i in &scenario.intersections {
        intersection(&mut x, i);
    }
    let legacy_2018b = scenario.version == "2018b";
    for o in &scenario.static_obstacles {
        static_obstacle(&mut x, legacy_2018b, o);
    }
    for o in &scenario.dynamic_obstacles {
        dynamic_obstacle(&mut x, legacy_2018b, o);
    }
    for p in &scenario.planning_problems {
        planning_problem(&mut x, p);
    }
    x.close("commonRoad");
    x.out
}

/// An XML document being written, two spaces of indent per level.
struct Xml {
    out: String,
    depth: usize,
}

impl Xml {
    fn start_tag(&mut self, name: &str, attrs: &[(&str, &str)]) {
        for _ in 0..self.depth {
            self.out.push_str("  ");
        }
        self.out.push('<');
        self.out.push_str(name);
        for (key, value) in attrs {
            // Writing into a String cannot fail (here and at every `let _ = write!`).
            let _ = write!(self.out, " {key}=\"");
            escape(&mut self.out, value);
            self.out.push('"');
        }
    }

    fn open(&mut self, name: &str, attrs: &[(&str, &str)]) {
        self.start_tag(name, attrs);
        self.out.push_str(">\n");
        self.depth += 1;
    }

    fn close(&mut self, name: &str) {
        self.depth = self.depth.saturating_sub(1);
        for _ in 0..self.depth {
            self.out.push_str("  ");
        }
        let _ = writeln!(self.out, "</{name}>");
    }

    fn empty(&mut self, name: &str, attrs: &[(&str, &str)]) {
        self.start_tag(name, attrs);
        self.out.push_str("/>\n");
    }

    /// `<name>text</name>`, the text escaped.
    fn text(&mut self, name: &str, text: &str) {
        self.start_tag(name, &[]);
        self.out.push('>');
        escape(&mut self.out, text);
        let _ = writeln!(self.out, "</{name}>");
    }

    /// `<name>value</name>` for a number, whose `Display` needs no escaping (for `f64`, the
    /// shortest text that reads back to the same bits).
    fn number(&mut self, name: &str, value: impl Display) {
        self.start_tag(name, &[]);
        let _ = writeln!(self.out, ">{value}</{name}>");
    }
}

/// Appends `s` escaped for text and attribute values alike.
fn escape(out: &mut String, s: &str) {
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // As references, so the reader's line-end and attribute-value normalisation keep them.
            '\t' | '\n' | '\r' => {
                let _ = write!(out, "&#{};", u32::from(c));
            }
            // Not allowed in XML 1.0, not even as references.
            '\0'..='\u{1f}' | '\u{fffe}' | '\u{ffff}' => out.push('\u{fffd}'),
            c => out.push(c),
        }
    }
}

/// An ASCII XML name without a colon: a letter or `_`, then letters, digits, `_`, `-` or `.`.
fn is_ascii_name(s: &str) -> bool {
    let mut chars = s.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
}

/// `<name><x>..</x><y>..</y></name>`.
fn xy(x: &mut Xml, name: &str, p: Vec2) {
    x.open(name, &[]);
    x.number("x", p.x);
    x.number("y", p.y);
    x.close(name);
}

fn points(x: &mut Xml, name: &str, ps: &[Vec2]) {
    x.open(name, &[]);
    for &p in ps {
        xy(x, "point", p);
    }
    x.close(name);
}

/// `<name ref="id"/>` for each id.
fn refs(x: &mut Xml, name: &str, ids: &[u64]) {
    for id in ids {
        x.empty(name, &[("ref", &id.to_string())]);
    }
}

/// `<name><exact>value</exact></name>`.
fn exact(x: &mut Xml, name: &str, value: impl Display) {
    x.open(name, &[]);
    x.number("exact", value);
    x.close(name);
}

fn time_interval(x: &mut Xml, start: i64, end: i64) {
    if start == end {
        return exact(x, "time", start);
    }
    x.open("time", &[]);
    x.number("intervalStart", start);
    x.number("intervalEnd", end);
    x.close("time");
}

fn lanelet(x: &mut Xml, l: &Lanelet) {
    x.open("lanelet", &[("id", &l.id.to_string())]);
    // The centreline, widths and polygon are derived from the bounds on reading.
    points(x, "leftBound", &l.left_bound);
    points(x, "rightBound", &l.right_bound);
    refs(x, "predecessor", &l.predecessors);
    refs(x, "successor", &l.successors);
    for (name, adjacency) in [("adjacentLeft", l.adjacent_left), ("adjacentRight", l.adjacent_right)] {
        if let Some(a) = adjacency {
            let dir = if a.same_direction { "same" } else { "opposite" };
            x.empty(name, &[("ref", &a.id.to_string()), ("drivingDir", dir)]);
        }
    }
    for t in &l.lanelet_types {
        x.text("laneletType", t);
    }
    x.close("lanelet");
}

fn intersection(x: &mut Xml, i: &Intersection) {
    x.open("intersection", &[("id", &i.id.to_string())]);
    for inc in &i.incomings {
        x.open("incoming", &[("id", &inc.id.to_string())]);
        refs(x, "incomingLanelet", &inc.incoming_lanelets);
        refs(x, "successorsRight", &inc.successors_right);
        refs(x, "successorsStraight", &inc.successors_straight);
        refs(x, "successorsLeft", &inc.successors_left);
        x.close("incoming");
    }
    x.close("intersection");
}

fn state(x: &mut Xml, name: &str, s: &ObstacleState) {
    x.open(name, &[]);
    x.open("position", &[]);
    xy(x, "point", s.position);
    x.close("position");
    exact(x, "orientation", s.orientation_rad);
    exact(x, "time", s.time_step);
    if let Some(v) = s.velocity_mps {
        exact(x, "velocity", v);
    }
    if let Some(a) = s.acceleration_mps2 {
        exact(x, "acceleration", a);
    }
    x.close(name);
}

/// One shape element. The centre and orientation are left out where they are the reader's
/// default (+0): CommonRoad's polygons have neither and its circles no orientation.
fn shape(x: &mut Xml, shape: &Shape, centre: Vec2, orientation_rad: f64) {
    let name = match shape {
        Shape::Rectangle { length_m, width_m } => {
            x.open("rectangle", &[]);
            x.number("length", length_m);
            x.number("width", width_m);
            "rectangle"
        }
        Shape::Circle { radius_m } => {
            x.open("circle", &[]);
            x.number("radius", radius_m);
            "circle"
        }
        Shape::Polygon { vertices } => {
            x.open("polygon", &[]);
            for &p in vertices {
                xy(x, "point", p);
            }
            "polygon"
        }
    };
    // Bits, not ==, so that -0 is written and reads back as -0.
    if orientation_rad.to_bits() != 0 {
        x.number("orientation", orientation_rad);
    }
    if centre.x.to_bits() != 0 || centre.y.to_bits() != 0 {
        xy(x, "center", centre);
    }
    x.close(name);
}

fn placed_shapes(x: &mut Xml, shapes: &[PlacedShape]) {
    x.open("shape", &[]);
    for s in shapes {
        shape(x, &s.shape, s.centre, s.orientation_rad);
    }
    x.close("shape");
}

/// Opens an obstacle element (`kind` is `dynamic` or `static`) and writes what both kinds have
/// before their predictions; returns the element's name, for closing it.
fn open_obstacle(
    x: &mut Xml,
    legacy_2018b: bool,
    kind: &str,
    id: u64,
    obstacle_type: &str,
    own_shape: &Shape,
    initial_state: &ObstacleState,
) -> String {
    let name = if legacy_2018b { "obstacle".to_string() } else { format!("{kind}Obstacle") };
    x.open(&name, &[("id", &id.to_string())]);
    if legacy_2018b {
        x.text("role", kind);
    }
    x.text("type", obstacle_type);
    // An obstacle's shape is centred on its state: no centre or orientation of its own.
    x.open("shape", &[]);
    shape(x, own_shape, Vec2::zeros(), 0.0);
    x.close("shape");
    state(x, "initialState", initial_state);
    name
}

fn static_obstacle(x: &mut Xml, legacy_2018b: bool, o: &StaticObstacle) {
    let name = open_obstacle(x, legacy_2018b, "static", o.id, &o.obstacle_type, &o.shape, &o.initial_state);
    x.close(&name);
}

fn dynamic_obstacle(x: &mut Xml, legacy_2018b: bool, o: &DynamicObstacle) {
    let name = open_obstacle(x, legacy_2018b, "dynamic", o.id, &o.obstacle_type, &o.shape, &o.initial_state);
    if !o.trajectory.is_empty() {
        x.open("trajectory", &[]);
        for s in &o.trajectory {
            state(x, "state", s);
        }
        x.close("trajectory");
    }
    if !o.occupancy_set.is_empty() {
        x.open("occupancySet", &[]);
        for occ in &o.occupancy_set {
            x.open("occupancy", &[]);
            placed_shapes(x, &occ.shapes);
            time_interval(x, occ.time_start, occ.time_end);
            x.close("occupancy");
        }
        x.close("occupancySet");
    }
    x.close(&name);
}

fn planning_problem(x: &mut Xml, p: &PlanningProblem) {
    x.open("planningProblem", &[("id", &p.id.to_string())]);
    state(x, "initialState", &p.initial_state);
    for _ in 0..p.goal_state_count {
        x.empty("goalState", &[]);
    }
    x.close("planningProblem");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Incoming, Occupancy};
    use crate::parse_scenario;
    use crate::{Adjacency, LaneletNetwork};

    /// Everything the model holds but its id indices, with `Debug`'s floats: equal text means
    /// equal bits, where `==` takes -0 for +0.
    fn bits(s: &Scenario) -> String {
        let parts = (&s.lanelets.lanelets, &s.dynamic_obstacles, &s.static_obstacles, &s.planning_problems);
        format!("{:?}", (&s.benchmark_id, &s.version, s.dt_s, &s.tags, parts, &s.intersections))
    }

    /// Writes `scenario` and reads it back: equal, bit for bit, and written again the same
    /// bytes (the reread's id indices hash in another order). Returns the text.
    fn assert_round_trip(name: &str, scenario: &Scenario) -> String {
        let text = to_xml(scenario);
        let back = match parse_scenario(&text) {
            Ok(back) => back,
            Err(e) => panic!("{name}: the written XML does not read back: {e}"),
        };
        // Not assert_eq!: a data file's Debug is megabytes.
        assert!(back == *scenario, "{name}: reads back different");
        assert!(bits(&back) == bits(scenario), "{name}: reads back with other bits");
        assert!(to_xml(&back) == text, "{name}: written again, the text differs");
        text
    }

    #[test]
    fn every_data_file_reads_back_equal() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/commonroad");
        let mut files: Vec<_> = std::fs::read_dir(&dir)
            .expect("data/commonroad is in the repository")
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "xml"))
            .collect();
        files.sort();
        assert!(files.len() >= 25, "{} XML files in {}", files.len(), dir.display());
        for path in files {
            let name = path.display().to_string();
            let original = std::fs::read_to_string(&path).expect("readable data file");
            let scenario = parse_scenario(&original).unwrap_or_else(|e| panic!("{name}: {e}"));
            let text = assert_round_trip(&name, &scenario);
            if scenario.version == "2018b" && !scenario.dynamic_obstacles.is_empty() {
                assert!(text.contains("<role>dynamic</role>"), "{name}: 2018b is written in its own layout");
            }
        }
    }

    /// A scenario as `cloud`'s ScenarioCollector rebuilds it from fleet messages (no tags,
    /// planning problems or intersections), with text to escape and awkward numbers.
    fn rebuilt() -> Scenario {
        let mut a = Lanelet::new(
            1,
            vec![Vec2::new(0.0, 3.5), Vec2::new(0.1 + 0.2, 3.5), Vec2::new(100.0, 3.5)],
            vec![Vec2::new(0.0, 0.0), Vec2::new(0.30000000000000004, -0.0), Vec2::new(100.0, 1e-7)],
        );
        a.successors = vec![2];
        a.adjacent_left = Some(Adjacency { id: 2, same_direction: false });
        a.lanelet_types = vec!["urban & <main>".into()];
        let mut b = Lanelet::new(
            2,
            vec![Vec2::new(100.0, 3.5), Vec2::new(200.0, 3.5)],
            vec![Vec2::new(100.0, 1e-7), Vec2::new(200.0, 0.0)],
        );
        b.predecessors = vec![1];
        let state = |time_step: i64, x_m: f64| ObstacleState {
            time_step,
            position: Vec2::new(x_m, 1.75),
            orientation_rad: std::f64::consts::FRAC_PI_6,
            velocity_mps: Some(50.0 / 3.6), // 50 km/h: no short decimal
            acceleration_mps2: if time_step == 3 { None } else { Some(-0.0) },
        };
        let car = DynamicObstacle {
            id: 7,
            obstacle_type: "car \"<estimated>\" & 'fused'".into(),
            shape: Shape::Rectangle { length_m: 4.508, width_m: 1.61 },
            initial_state: state(2, 10.0),
            trajectory: vec![state(3, 11.3888888888889), state(4, 12.777777777777779)],
            occupancy_set: Vec::new(),
        };
        let parked = StaticObstacle {
            id: 9,
            obstacle_type: "unknown\tkind\r\nline two".into(),
            shape: Shape::Circle { radius_m: 0.75 },
            initial_state: state(0, 50.0),
        };
        let dt_ns: i64 = 40_000_000;
        let site = "site <A&B> \"north\"\t'gate'".to_string();
        Scenario::from_parts(site, dt_ns as f64 / 1e9, LaneletNetwork::new(vec![a, b]), vec![car], vec![parked])
            .expect("unique obstacle ids")
    }

    #[test]
    fn a_rebuilt_scenario_with_text_to_escape_reads_back_equal() {
        let mut scenario = rebuilt();
        assert_round_trip("rebuilt", &scenario);
        // And the parts a rebuilt scenario lacks, some in shapes CommonRoad files do not use.
        scenario.tags = vec!["urban".into(), "cut_in".into()];
        scenario.dynamic_obstacles[0].occupancy_set = vec![Occupancy {
            time_start: 5,
            time_end: 8,
            shapes: vec![
                PlacedShape {
                    shape: Shape::Rectangle { length_m: 5.0, width_m: 2.0 },
                    centre: Vec2::new(20.0, -0.0),
                    orientation_rad: -0.0,
                },
                PlacedShape { shape: Shape::Circle { radius_m: 1.0 }, centre: Vec2::zeros(), orientation_rad: 0.25 },
                PlacedShape {
                    shape: Shape::Polygon { vertices: vec![Vec2::zeros(), Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0)] },
                    centre: Vec2::new(3.0, 4.0),
                    orientation_rad: 0.0,
                },
            ],
        }];
        scenario.intersections = vec![Intersection {
            id: 30,
            incomings: vec![Incoming { id: 31, incoming_lanelets: vec![1], ..Default::default() }],
        }];
        scenario.planning_problems = vec![PlanningProblem {
            id: 7,
            initial_state: scenario.dynamic_obstacles[0].initial_state,
            goal_state_count: 2,
        }];
        assert_round_trip("rebuilt, with the rest", &scenario);
    }

    #[test]
    fn the_written_xml_is_well_formed_with_the_commonroad_root() {
        let scenario = rebuilt();
        let text = to_xml(&scenario);
        let doc = roxmltree::Document::parse(&text).expect("well-formed XML");
        let root = doc.root_element();
        assert_eq!(root.tag_name().name(), "commonRoad");
        assert_eq!(root.attribute("commonRoadVersion"), Some("2020a"));
        assert_eq!(root.attribute("benchmarkID"), Some("site <A&B> \"north\"\t'gate'"));
        assert_eq!(root.attribute("timeStepSize"), Some("0.04"));
        let names: Vec<&str> = root.children().filter(|n| n.is_element()).map(|n| n.tag_name().name()).collect();
        assert_eq!(names, ["lanelet", "lanelet", "staticObstacle", "dynamicObstacle"]);
    }

    #[test]
    fn what_xml_cannot_carry_is_left_out_or_replaced() {
        let mut scenario = rebuilt();
        scenario.tags = vec!["two words".into(), "interstate".into(), "x:y".into()];
        scenario.static_obstacles[0].obstacle_type = "bell\u{7}".into();
        let back = parse_scenario(&to_xml(&scenario)).expect("still well-formed");
        assert_eq!(back.tags, ["interstate"]);
        assert_eq!(back.static_obstacles[0].obstacle_type, "bell\u{fffd}");
    }
}
