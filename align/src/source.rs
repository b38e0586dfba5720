//! Source names mapped to small dense indices, so the hot path indexes arrays, not hash maps.

use std::collections::HashMap;

/// A source (vehicle, RSU, replay) as a dense index assigned in order of first appearance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SourceIndex(pub u32);

impl SourceIndex {
    /// The index as a `usize`, for indexing per-source arrays.
    pub const fn as_usize(self) -> usize {
        self.0 as usize
    }
}

/// A new source name was refused because the table is full.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("source `{name}` refused: the table already holds its limit of {limit} sources")]
pub struct TooManySources {
    pub name: String,
    pub limit: usize,
}

/// Names → [`SourceIndex`], bounded so garbage source ids off the wire cannot grow it for ever.
///
/// Indices are handed out in order of first appearance, so the same input order gives the same
/// indices (the map's hash order never leaks out).
#[derive(Debug, Clone)]
pub struct SourceTable {
    by_name: HashMap<String, SourceIndex>,
    names: Vec<String>,
    limit: usize,
}

impl SourceTable {
    /// An empty table that accepts at most `limit` distinct sources.
    pub fn with_limit(limit: usize) -> Self {
        Self { by_name: HashMap::new(), names: Vec::new(), limit }
    }

    /// The index of `name`, assigning the next one if it is new (the only case that allocates).
    pub fn index_of(&mut self, name: &str) -> Result<SourceIndex, TooManySources> {
        if let Some(&idx) = self.by_name.get(name) {
            return Ok(idx);
        }
        if self.names.len() >= self.limit || self.names.len() >= u32::MAX as usize {
            return Err(TooManySources { name: name.to_owned(), limit: self.limit });
        }
        let idx = SourceIndex(self.names.len() as u32);
        self.names.push(name.to_owned());
        self.by_name.insert(name.to_owned(), idx);
        Ok(idx)
    }

    /// The index of `name` if it is known; never assigns.
    pub fn get(&self, name: &str) -> Option<SourceIndex> {
        self.by_name.get(name).copied()
    }

    /// The name behind `idx`.
    pub fn name(&self, idx: SourceIndex) -> Option<&str> {
        self.names.get(idx.as_usize()).map(String::as_str)
    }

    /// How many sources are known.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether no source is known yet.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assigns_dense_indices_in_first_seen_order() {
        let mut t = SourceTable::with_limit(3);
        assert_eq!(t.index_of("veh-7"), Ok(SourceIndex(0)));
        assert_eq!(t.index_of("rsu-1"), Ok(SourceIndex(1)));
        assert_eq!(t.index_of("veh-7"), Ok(SourceIndex(0)));
        assert_eq!(t.get("rsu-1"), Some(SourceIndex(1)));
        assert_eq!(t.get("nope"), None);
        assert_eq!(t.name(SourceIndex(1)), Some("rsu-1"));
        assert_eq!(t.name(SourceIndex(2)), None);
        assert_eq!(t.len(), 2);
    }

    #[test]
    fn refuses_sources_beyond_the_limit() {
        let mut t = SourceTable::with_limit(1);
        assert_eq!(t.index_of("a"), Ok(SourceIndex(0)));
        let err = t.index_of("b").unwrap_err();
        assert_eq!(err, TooManySources { name: "b".into(), limit: 1 });
        assert!(err.to_string().contains("`b`"));
        assert_eq!(t.index_of("a"), Ok(SourceIndex(0)), "known sources still resolve when full");
    }
}
