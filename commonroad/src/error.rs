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
    /// A document longer than [`super::limits::MAX_XML_BYTES`].
    #[error("the file is {bytes} bytes, more than the {max} a CommonRoad file may have")]
    TooLarge { bytes: u64, max: u64 },
    /// Elements nested deeper than [`super::limits::MAX_DEPTH`].
    #[error("line {line}: elements nested deeper than {max} levels (CommonRoad nests about 8)")]
    TooDeep { line: u32, max: usize },
    /// More XML nodes than [`super::limits::MAX_NODES`].
    #[error("more than {max} XML nodes (elements and texts)")]
    TooManyNodes { max: u32 },
    /// Two dynamic obstacles with one id (in a scenario built from parts).
    #[error("dynamic obstacle id {id} appears twice")]
    DuplicateObstacle { id: u64 },
}
