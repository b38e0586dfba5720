//! What can be wrong with a CommonRoad file: every error names the element (with its id where it
//! has one, and the line) and the reason.

/// A CommonRoad document that cannot be read into a [`super::Scenario`].
#[derive(Debug, thiserror::Error)]
pub enum CommonRoadError {
    /// The text is not well-formed XML (roxmltree's message carries line and column).
    #[error("not well-formed XML: {0}")]
    Xml(#[from] roxmltree::Error),
    /// The root element is something else than `<commonRoad>`.
    #[error("root element <{root}> is not <commonRoad>")]
    NotCommonRoad { root: String },
    /// A required child element or attribute is absent.
    #[error("<{element}> (line {line}): missing {what}")]
    Missing { element: String, line: u32, what: String },
    /// A value that does not parse or is out of its domain.
    #[error("<{element}> (line {line}): '{value}' is not {expected}")]
    BadValue { element: String, line: u32, value: String, expected: &'static str },
    /// A structurally valid element whose content is inconsistent.
    #[error("<{element}> (line {line}): {reason}")]
    Invalid { element: String, line: u32, reason: String },
    /// Two dynamic obstacles with one id (in a scenario built from parts).
    #[error("dynamic obstacle id {id} appears twice")]
    DuplicateObstacle { id: u64 },
}
