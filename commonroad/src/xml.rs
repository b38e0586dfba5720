//! Small typed accessors over roxmltree nodes that turn every absence or bad value into a
//! [`CommonRoadError`] naming the element, its id and line, and the compacted text they are
//! parsed from.

use super::error::CommonRoadError;
use risktwin_common::geometry::Vec2;
use roxmltree::Node;

/// A document's text without the whitespace-only runs between a `>` and the next `<`, and
/// where they were, so positions map back to lines of the original.
///
/// CommonRoad files are indented: half of roxmltree's nodes are those runs, and the node
/// vector outgrows the capacity roxmltree reserves (one node per `<`), so parsing the original
/// copied and faulted in the whole tree twice (profile of `risktwin criticality` on
/// DEU_AAH1-2_7900: roxmltree was 60 % of the process). No element, attribute or non-blank text
/// changes: a `<` cannot occur inside an attribute value, and blank text reads as empty either
/// way ([`El::text`] trims).
pub(crate) struct Source<'t> {
    original: &'t str,
    /// The text roxmltree parses.
    pub compact: String,
    /// (position in `compact`, bytes removed before it), one entry per removed run, ascending.
    shifts: Vec<(usize, usize)>,
}

impl<'t> Source<'t> {
    pub fn new(original: &'t str) -> Self {
        let bytes = original.as_bytes();
        let mut compact = Vec::with_capacity(bytes.len());
        let mut shifts = Vec::new();
        let mut removed = 0;
        let mut i = 0;
        while let Some(k) = bytes[i..].iter().position(|&b| b == b'>') {
            let end = i + k + 1;
            compact.extend_from_slice(&bytes[i..end]);
            let blank = bytes[end..].iter().take_while(|b| b.is_ascii_whitespace()).count();
            i = end;
            if blank > 0 && bytes.get(end + blank) == Some(&b'<') {
                removed += blank;
                shifts.push((compact.len(), removed));
                i += blank;
            }
        }
        compact.extend_from_slice(&bytes[i..]);
        // Only ASCII whitespace between two ASCII bytes was removed: still UTF-8.
        let compact = String::from_utf8(compact).expect("removing ASCII runs keeps UTF-8");
        Self { original, compact, shifts }
    }

    /// 1-based line, in the original text, of position `pos` of the compacted one.
    pub fn line_at(&self, pos: usize) -> u32 {
        let shift = match self.shifts.partition_point(|&(at, _)| at <= pos) {
            0 => 0,
            k => self.shifts[k - 1].1,
        };
        let end = (pos + shift).min(self.original.len());
        1 + self.original.as_bytes()[..end].iter().filter(|&&b| b == b'\n').count() as u32
    }
}

/// An element plus the source, so errors can report the line.
#[derive(Clone, Copy)]
pub(crate) struct El<'a, 'input> {
    pub node: Node<'a, 'input>,
    source: &'a Source<'a>,
}

impl<'a, 'input> El<'a, 'input> {
    pub fn new(source: &'a Source<'a>, node: Node<'a, 'input>) -> Self {
        Self { node, source }
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
        self.source.line_at(self.node.range().start)
    }

    /// Element children named `name`.
    pub fn children(&self, name: &'static str) -> impl Iterator<Item = El<'a, 'input>> + 'a {
        let source = self.source;
        self.node.children().filter(move |c| c.is_element() && c.has_tag_name(name)).map(move |n| El::new(source, n))
    }

    /// All element children.
    pub fn elements(&self) -> impl Iterator<Item = El<'a, 'input>> + 'a {
        let source = self.source;
        self.node.children().filter(|c| c.is_element()).map(move |n| El::new(source, n))
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
