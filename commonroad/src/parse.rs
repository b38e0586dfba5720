//! CommonRoad XML (2020a, and the 2018b `<obstacle role=...>` layout) → [`Scenario`].
//!
//! Pure: text in, typed scenario or a [`CommonRoadError`] out. Elements the measures and the
//! twin do not use (traffic signs and lights, location, goal-region details) are skipped.

use super::error::CommonRoadError;
use super::limits;
use super::model::{
    DynamicObstacle, Incoming, Intersection, ObstacleState, Occupancy, PlacedShape, PlanningProblem, Scenario, Shape,
    StaticObstacle,
};
use super::xml::{El, Source};
use crate::{Adjacency, Lanelet, LaneletNetwork};
use risktwin_common::geometry::Vec2;
use std::collections::{HashMap, HashSet};

/// Parses a CommonRoad XML document.
///
/// A document over the [`limits`](super::limits) (size, nesting depth, nodes) is refused
/// before or while roxmltree reads it.
pub fn parse_scenario(text: &str) -> Result<Scenario, CommonRoadError> {
    limits::check_size(text)?;
    limits::check_depth(text)?;
    let options = roxmltree::ParsingOptions { allow_dtd: false, nodes_limit: limits::MAX_NODES };
    let source = Source::new(text);
    let doc = match roxmltree::Document::parse_with_options(&source.compact, options) {
        Ok(doc) => doc,
        Err(roxmltree::Error::NodesLimitReached) => {
            return Err(CommonRoadError::TooManyNodes { max: limits::MAX_NODES });
        }
        // Report the error with the original's positions (the original has more nodes: the
        // blank runs between tags, so the limit is not applied to it).
        Err(e) => {
            let original = roxmltree::ParsingOptions { allow_dtd: false, nodes_limit: u32::MAX };
            return Err(roxmltree::Document::parse_with_options(text, original).err().unwrap_or(e).into());
        }
    };
    let root = El::new(&source, doc.root_element());
    if root.node.tag_name().name() != "commonRoad" {
        return Err(CommonRoadError::NotCommonRoad { root: root.node.tag_name().name().to_string() });
    }
    let dt_text = root.node.attribute("timeStepSize").ok_or_else(|| root.missing("attribute 'timeStepSize'".into()))?;
    let dt_s = match dt_text.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => x,
        _ => return Err(root.invalid(format!("timeStepSize '{dt_text}' is not a positive number of seconds"))),
    };
    let mut lanelets = Vec::new();
    let mut dynamic_obstacles = Vec::new();
    let mut static_obstacles = Vec::new();
    let mut planning_problems = Vec::new();
    let mut intersections = Vec::new();
    let mut tags = Vec::new();
    for el in root.elements() {
        match el.node.tag_name().name() {
            "lanelet" => lanelets.push(lanelet(&el)?),
            "dynamicObstacle" => dynamic_obstacles.push(dynamic_obstacle(&el)?),
            "staticObstacle" => static_obstacles.push(static_obstacle(&el)?),
            // 2018b: one element for both kinds, told apart by <role>.
            "obstacle" => match el.req("role")?.text() {
                "dynamic" => dynamic_obstacles.push(dynamic_obstacle(&el)?),
                "static" => static_obstacles.push(static_obstacle(&el)?),
                other => return Err(el.invalid(format!("role '{other}' is neither 'dynamic' nor 'static'"))),
            },
            "planningProblem" => planning_problems.push(planning_problem(&el)?),
            "intersection" => intersections.push(intersection(&el)?),
            "scenarioTags" => tags.extend(el.elements().map(|t| t.node.tag_name().name().to_string())),
            _ => {}
        }
    }
    let mut seen = HashSet::new();
    if let Some(dup) = lanelets.iter().map(|l| l.id).find(|id| !seen.insert(*id)) {
        return Err(root.invalid(format!("lanelet id {dup} appears twice")));
    }
    let mut dynamic_index = HashMap::new();
    for (i, o) in dynamic_obstacles.iter().enumerate() {
        if dynamic_index.insert(o.id, i).is_some() {
            return Err(root.invalid(format!("dynamic obstacle id {} appears twice", o.id)));
        }
    }
    Ok(Scenario {
        benchmark_id: root.node.attribute("benchmarkID").unwrap_or_default().to_string(),
        version: root.node.attribute("commonRoadVersion").unwrap_or_default().to_string(),
        dt_s,
        tags,
        lanelets: LaneletNetwork::new(lanelets),
        dynamic_obstacles,
        static_obstacles,
        planning_problems,
        intersections,
        dynamic_index,
    })
}

fn points(el: &El) -> Result<Vec<Vec2>, CommonRoadError> {
    el.children("point").map(|p| p.point()).collect()
}

fn refs(el: &El, name: &'static str) -> Result<Vec<u64>, CommonRoadError> {
    el.children(name).map(|c| c.id_attr("ref")).collect()
}

fn lanelet(el: &El) -> Result<Lanelet, CommonRoadError> {
    let id = el.id_attr("id")?;
    let left = points(&el.req("leftBound")?)?;
    let right = points(&el.req("rightBound")?)?;
    if left.len() < 2 || left.len() != right.len() {
        return Err(el.invalid(format!(
            "bounds need the same number of points (at least 2): left has {}, right has {}",
            left.len(),
            right.len()
        )));
    }
    let mut l = Lanelet::new(id, left, right);
    l.predecessors = refs(el, "predecessor")?;
    l.successors = refs(el, "successor")?;
    let adjacency = |name: &'static str| -> Result<Option<Adjacency>, CommonRoadError> {
        let Some(a) = el.opt(name) else { return Ok(None) };
        let dir = a.node.attribute("drivingDir").unwrap_or("same");
        let same_direction = match dir {
            "same" => true,
            "opposite" => false,
            other => return Err(a.invalid(format!("drivingDir '{other}' is neither 'same' nor 'opposite'"))),
        };
        Ok(Some(Adjacency { id: a.id_attr("ref")?, same_direction }))
    };
    l.adjacent_left = adjacency("adjacentLeft")?;
    l.adjacent_right = adjacency("adjacentRight")?;
    l.lanelet_types = el.children("laneletType").map(|t| t.text().to_string()).collect();
    Ok(l)
}

/// A state of an obstacle or planning problem: position point, orientation and time required,
/// velocity and acceleration optional.
fn state(el: &El) -> Result<ObstacleState, CommonRoadError> {
    let pos = el.req("position")?;
    let position = match pos.opt("point") {
        Some(p) => p.point()?,
        None => return Err(pos.invalid("a state position must be a <point> (not a region)".into())),
    };
    let time = el.req("time")?;
    let (t0, t1) = time.time_interval()?;
    if t0 != t1 {
        return Err(time.invalid("an interval where an exact time step is needed".into()));
    }
    let opt = |name: &'static str| el.opt(name).map(|e| e.exact_f64()).transpose();
    Ok(ObstacleState {
        time_step: t0,
        position,
        orientation_rad: el.req("orientation")?.exact_f64()?,
        velocity_mps: opt("velocity")?,
        acceleration_mps2: opt("acceleration")?,
    })
}

fn positive(el: &El, name: &'static str) -> Result<f64, CommonRoadError> {
    let c = el.req(name)?;
    let x = c.f64()?;
    if x > 0.0 { Ok(x) } else { Err(c.invalid(format!("{name} {x} must be positive"))) }
}

/// The shapes inside a `<shape>` element, with their centres and orientations.
fn shapes(el: &El) -> Result<Vec<PlacedShape>, CommonRoadError> {
    let mut out = Vec::new();
    for s in el.elements() {
        let centre = s.opt("center").map(|c| c.point()).transpose()?.unwrap_or_else(Vec2::zeros);
        let orientation_rad = s.opt("orientation").map(|o| o.f64()).transpose()?.unwrap_or(0.0);
        let shape = match s.node.tag_name().name() {
            "rectangle" => Shape::Rectangle { length_m: positive(&s, "length")?, width_m: positive(&s, "width")? },
            "circle" => Shape::Circle { radius_m: positive(&s, "radius")? },
            "polygon" => {
                let vertices = points(&s)?;
                if vertices.len() < 3 {
                    return Err(s.invalid(format!("a polygon needs at least 3 points, has {}", vertices.len())));
                }
                Shape::Polygon { vertices }
            }
            other => return Err(s.invalid(format!("unsupported shape <{other}>"))),
        };
        out.push(PlacedShape { shape, centre, orientation_rad });
    }
    Ok(out)
}

/// An obstacle's own shape: exactly one, centred on its state.
fn obstacle_shape(el: &El) -> Result<Shape, CommonRoadError> {
    let s = el.req("shape")?;
    let mut all = shapes(&s)?;
    match all.len() {
        1 => Ok(all.remove(0).shape),
        n => Err(s.invalid(format!("an obstacle needs exactly one shape, found {n}"))),
    }
}

fn dynamic_obstacle(el: &El) -> Result<DynamicObstacle, CommonRoadError> {
    let id = el.id_attr("id")?;
    let initial_state = state(&el.req("initialState")?)?;
    let mut trajectory = Vec::new();
    if let Some(tr) = el.opt("trajectory") {
        let mut states = tr.children("state").map(|s| state(&s).map(|st| (s, st))).peekable();
        // Some 2020a files (ZAM_Zip-2_1, ZAM_Urban-3_3_Repair) repeat the initial state as the
        // trajectory's first state. commonroad-io accepts them: `Obstacle.state_at_time` answers
        // the initial step from `initial_state` and never consults the trajectory's copy. So do we.
        if let Some(Ok((_, first))) = states.peek()
            && first.time_step == initial_state.time_step
        {
            states.next();
        }
        for (expected, item) in (initial_state.time_step + 1..).zip(states) {
            let (s, st) = item?;
            if st.time_step != expected {
                return Err(s.invalid(format!(
                    "time step {} where {expected} should follow (trajectories are consecutive)",
                    st.time_step
                )));
            }
            trajectory.push(st);
        }
    }
    let mut occupancy_set = Vec::new();
    if let Some(set) = el.opt("occupancySet") {
        for o in set.children("occupancy") {
            let (time_start, time_end) = o.req("time")?.time_interval()?;
            occupancy_set.push(Occupancy { time_start, time_end, shapes: shapes(&o.req("shape")?)? });
        }
    }
    Ok(DynamicObstacle {
        id,
        obstacle_type: el.req("type")?.text().to_string(),
        shape: obstacle_shape(el)?,
        initial_state,
        trajectory,
        occupancy_set,
    })
}

fn static_obstacle(el: &El) -> Result<StaticObstacle, CommonRoadError> {
    Ok(StaticObstacle {
        id: el.id_attr("id")?,
        obstacle_type: el.req("type")?.text().to_string(),
        shape: obstacle_shape(el)?,
        initial_state: state(&el.req("initialState")?)?,
    })
}

fn planning_problem(el: &El) -> Result<PlanningProblem, CommonRoadError> {
    Ok(PlanningProblem {
        id: el.id_attr("id")?,
        initial_state: state(&el.req("initialState")?)?,
        goal_state_count: el.children("goalState").count(),
    })
}

fn intersection(el: &El) -> Result<Intersection, CommonRoadError> {
    let incomings = el
        .children("incoming")
        .map(|inc| {
            Ok(Incoming {
                id: inc.id_attr("id")?,
                incoming_lanelets: refs(&inc, "incomingLanelet")?,
                successors_right: refs(&inc, "successorsRight")?,
                successors_straight: refs(&inc, "successorsStraight")?,
                successors_left: refs(&inc, "successorsLeft")?,
            })
        })
        .collect::<Result<_, CommonRoadError>>()?;
    Ok(Intersection { id: el.id_attr("id")?, incomings })
}

#[cfg(test)]
mod tests {
    use super::*;

    const LANELET: &str = r#"<lanelet id="1"><leftBound><point><x>0</x><y>3</y></point><point><x>100</x><y>3</y></point></leftBound>
        <rightBound><point><x>0</x><y>0</y></point><point><x>100</x><y>0</y></point></rightBound>
        <successor ref="2"/><adjacentLeft ref="5" drivingDir="opposite"/><laneletType>driveWay</laneletType></lanelet>"#;

    fn state(tag: &str, t: i64, x: f64, v: f64) -> String {
        format!(
            "<{tag}><position><point><x>{x}</x><y>1.5</y></point></position><orientation><exact>0</exact></orientation>\
             <time><exact>{t}</exact></time><velocity><exact>{v}</exact></velocity><acceleration><exact>0.5</exact></acceleration></{tag}>"
        )
    }

    fn doc(body: &str) -> String {
        format!(
            r#"<?xml version="1.0"?><commonRoad timeStepSize="0.1" commonRoadVersion="2020a" benchmarkID="T-1">{body}</commonRoad>"#
        )
    }

    fn car(id: u64, states: &[(i64, f64)]) -> String {
        let init = state("initialState", states[0].0, states[0].1, 10.0);
        let traj: String = states[1..].iter().map(|&(t, x)| state("state", t, x, 10.0)).collect();
        format!(
            r#"<dynamicObstacle id="{id}"><type>car</type><shape><rectangle><length>4.5</length><width>2</width></rectangle></shape>{init}<trajectory>{traj}</trajectory></dynamicObstacle>"#
        )
    }

    #[test]
    fn reads_lanelets_obstacles_and_planning_problem() {
        let pp =
            format!(r#"<planningProblem id="7">{}<goalState/></planningProblem>"#, state("initialState", 0, 5.0, 9.0));
        let text = doc(&format!(
            "<scenarioTags><interstate/></scenarioTags>{LANELET}{}{}{pp}",
            car(7, &[(0, 5.0), (1, 6.0), (2, 7.0)]),
            car(8, &[(1, 30.0), (2, 31.0)])
        ));
        let s = parse_scenario(&text).unwrap();
        assert_eq!((s.benchmark_id.as_str(), s.dt_s, s.tags.as_slice()), ("T-1", 0.1, &["interstate".to_string()][..]));
        let l = s.lanelets.get(1).unwrap();
        assert_eq!(l.centreline[1], Vec2::new(100.0, 1.5));
        assert_eq!(l.widths_m, vec![3.0, 3.0]);
        assert_eq!(l.successors, vec![2]);
        assert_eq!(l.adjacent_left, Some(Adjacency { id: 5, same_direction: false }));
        assert_eq!(l.lanelet_types, vec!["driveWay"]);
        let o = s.dynamic_obstacle(8).unwrap();
        assert_eq!((o.first_time_step(), o.last_time_step()), (1, 2));
        assert_eq!(o.state_at(2).map(|st| st.position.x), Some(31.0));
        assert!(o.state_at(0).is_none() && o.state_at(3).is_none());
        assert_eq!(o.shape, Shape::Rectangle { length_m: 4.5, width_m: 2.0 });
        assert_eq!(o.initial_state.acceleration_mps2, Some(0.5));
        assert_eq!(s.default_ego_id(), Some(7), "the planning problem's id names the ego");
        assert_eq!(s.planning_problems[0].goal_state_count, 1);
    }

    fn error(body: &str) -> String {
        parse_scenario(&doc(body)).unwrap_err().to_string()
    }

    #[test]
    fn a_trajectory_repeating_the_initial_state_is_read_as_commonroad_io_reads_it() {
        // As in ZAM_Zip-2_1_T-1: initial state at 0, trajectory 0, 1, 2 (its 0 a copy).
        let s = parse_scenario(&doc(&car(4, &[(0, 0.0), (0, 9.0), (1, 1.0), (2, 2.0)]))).unwrap();
        let o = s.dynamic_obstacle(4).unwrap();
        assert_eq!((o.first_time_step(), o.last_time_step(), o.trajectory.len()), (0, 2, 2));
        assert_eq!(o.state_at(0).map(|st| st.position.x), Some(0.0), "the initial state wins at its step");
        assert_eq!(o.state_at(1).map(|st| st.position.x), Some(1.0));
        // A repeat anywhere else is still a gap.
        let later = car(4, &[(0, 0.0), (1, 1.0), (1, 1.0)]);
        assert!(error(&later).contains("time step 1 where 2 should follow"), "{}", error(&later));
    }

    #[test]
    fn lines_are_those_of_the_indented_original() {
        // Parsed without the blank runs between tags (xml::Source); errors still name the
        // original lines, and XML errors are roxmltree's on the original.
        let text = "<commonRoad timeStepSize=\"0.1\">\n  <lanelet id=\"4\">\n    <leftBound>\n      \
                    <point><x>0</x><y>0</y></point>\n      <point>\r\n\t<x>1</x><y>z</y></point>\n    </leftBound>\n  \
                    </lanelet>\n</commonRoad>\n";
        assert_eq!(parse_scenario(text).unwrap_err().to_string(), "<y> (line 6): 'z' is not a finite number");
        let no_right = text.replace("<y>z</y>", "<y>1</y>");
        assert_eq!(parse_scenario(&no_right).unwrap_err().to_string(), "<lanelet id=4> (line 2): missing <rightBound>");
        let truncated = &text[..text.len() - 20];
        let expected = roxmltree::Document::parse(truncated).unwrap_err();
        assert_eq!(parse_scenario(truncated).unwrap_err().to_string(), format!("not well-formed XML: {expected}"));
    }

    #[test]
    fn errors_name_element_and_reason() {
        let no_right = r#"<lanelet id="4"><leftBound><point><x>0</x><y>0</y></point></leftBound></lanelet>"#;
        assert_eq!(error(no_right), "<lanelet id=4> (line 1): missing <rightBound>");
        let bad_x = LANELET.replace("<x>100</x><y>3</y>", "<x>abc</x><y>3</y>");
        assert_eq!(error(&bad_x), "<x> (line 1): 'abc' is not a finite number");
        let gap = car(3, &[(0, 0.0), (1, 1.0), (3, 3.0)]);
        assert!(error(&gap).contains("<state> (line 1): time step 3 where 2 should follow"), "{}", error(&gap));
        let no_shape = car(3, &[(0, 0.0)]).replace("<length>4.5</length>", "");
        assert!(error(&no_shape).contains("<rectangle> (line 1): missing <length>"), "{}", error(&no_shape));
        assert!(parse_scenario("<osm/>").unwrap_err().to_string().contains("<osm> is not <commonRoad>"));
        assert!(parse_scenario("<commonRoad").unwrap_err().to_string().starts_with("not well-formed XML"));
        let dt = r#"<commonRoad timeStepSize="-1"/>"#;
        assert!(parse_scenario(dt).unwrap_err().to_string().contains("timeStepSize '-1'"));
        let before = car(3, &[(5, 0.0), (4, 1.0)]);
        assert!(error(&before).contains("time step 4 where 6 should follow"), "{}", error(&before));
        let twice = format!("{}{}", car(3, &[(0, 0.0)]), car(3, &[(0, 0.0)]));
        assert!(error(&twice).contains("dynamic obstacle id 3 appears twice"));
    }
}
