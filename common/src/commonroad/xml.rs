//! Small typed accessors over roxmltree nodes that turn every absence or bad value into a
//! [`CommonRoadError`] naming the element, its id and line.

use super::error::CommonRoadError;
use crate::geometry::Vec2;
use roxmltree::{Document, Node};

/// An element plus the document, so errors can report the line.
#[derive(Clone, Copy)]
pub(crate) struct El<'a, 'input> {
    pub node: Node<'a, 'input>,
    doc: &'a Document<'input>,
}

impl<'a, 'input> El<'a, 'input> {
    pub fn new(doc: &'a Document<'input>, node: Node<'a, 'input>) -> Self {
        Self { node, doc }
    }

    /// `name` or `name id=N` of this element.
    pub fn label(&self) -> String {
        let name = self.node.tag_name().name();
        match self.node.attribute("id") {
            Some(id) => format!("{name} id={id}"),
            None => name.to_string(),
        }
    }

    /// 1-based line of the element's start tag.
    pub fn line(&self) -> u32 {
        self.doc.text_pos_at(self.node.range().start).row
    }

    /// Element children named `name`.
    pub fn children(&self, name: &'static str) -> impl Iterator<Item = El<'a, 'input>> + 'a {
        let doc = self.doc;
        self.node.children().filter(move |c| c.is_element() && c.has_tag_name(name)).map(move |n| El::new(doc, n))
    }

    /// All element children.
    pub fn elements(&self) -> impl Iterator<Item = El<'a, 'input>> + 'a {
        let doc = self.doc;
        self.node.children().filter(|c| c.is_element()).map(move |n| El::new(doc, n))
    }

    /// The first child named `name`, if any.
    pub fn opt(&self, name: &'static str) -> Option<El<'a, 'input>> {
        self.children(name).next()
    }

    /// The first child named `name`, or a `Missing` error.
    pub fn req(&self, name: &'static str) -> Result<El<'a, 'input>, CommonRoadError> {
        self.opt(name).ok_or_else(|| self.missing(format!("<{name}>")))
    }

    pub fn missing(&self, what: String) -> CommonRoadError {
        CommonRoadError::Missing { element: self.label(), line: self.line(), what }
    }

    pub fn invalid(&self, reason: String) -> CommonRoadError {
        CommonRoadError::Invalid { element: self.label(), line: self.line(), reason }
    }

    fn bad(&self, value: &str, expected: &'static str) -> CommonRoadError {
        CommonRoadError::BadValue { element: self.label(), line: self.line(), value: value.to_string(), expected }
    }

    /// The trimmed text content (empty when none).
    pub fn text(&self) -> &'a str {
        self.node.text().map_or("", str::trim)
    }

    /// The text as a finite number.
    pub fn f64(&self) -> Result<f64, CommonRoadError> {
        let t = self.text();
        match t.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => Err(self.bad(t, "a finite number")),
        }
    }

    /// The text as an integer (CommonRoad writes time steps as integers; `12.0` is accepted).
    pub fn i64(&self) -> Result<i64, CommonRoadError> {
        let t = self.text();
        if let Ok(k) = t.parse::<i64>() {
            return Ok(k);
        }
        match t.parse::<f64>() {
            Ok(x) if x.fract() == 0.0 && x.abs() < 1e15 => Ok(x as i64),
            _ => Err(self.bad(t, "an integer")),
        }
    }

    /// The `id` attribute (or another named attribute) as a non-negative integer.
    pub fn id_attr(&self, attr: &'static str) -> Result<u64, CommonRoadError> {
        let v = self.node.attribute(attr).ok_or_else(|| self.missing(format!("attribute '{attr}'")))?;
        v.trim().parse::<u64>().map_err(|_| self.bad(v, "a non-negative integer id"))
    }

    /// A `<x>`/`<y>` point.
    pub fn point(&self) -> Result<Vec2, CommonRoadError> {
        Ok(Vec2::new(self.req("x")?.f64()?, self.req("y")?.f64()?))
    }

    /// The `<exact>` value of a state field; intervals are refused where an exact value is needed.
    pub fn exact_f64(&self) -> Result<f64, CommonRoadError> {
        match self.opt("exact") {
            Some(e) => e.f64(),
            None if self.opt("intervalStart").is_some() => {
                Err(self.invalid("an interval where an exact value is needed".into()))
            }
            None => Err(self.missing("<exact>".into())),
        }
    }

    /// An `<exact>` time step, or `[intervalStart, intervalEnd]` as a pair.
    pub fn time_interval(&self) -> Result<(i64, i64), CommonRoadError> {
        if let Some(e) = self.opt("exact") {
            let k = e.i64()?;
            return Ok((k, k));
        }
        let (a, b) = (self.req("intervalStart")?.i64()?, self.req("intervalEnd")?.i64()?);
        if a > b {
            return Err(self.invalid(format!("interval start {a} is after its end {b}")));
        }
        Ok((a, b))
    }
}
