//! Warnings with a cap per kind, so a file with a million faulty faces still gives a readable
//! report: the first few of each kind in full, then one line saying how many more there were.
//! Unsupported statements are summarised per keyword at the end instead, with their count.

use std::collections::BTreeMap;

use crate::import::{Location, TriangleSink};

/// How many warnings of one kind are passed on in full.
const SHOWN: u64 = 10;
/// How many distinct unsupported keywords are told apart; a file inventing more gets them
/// summed under one line.
const KEYWORDS: usize = 32;

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Kind {
    /// A material library could not be used, or one of its statements is malformed.
    Library,
    /// `usemtl` names a material no library defines.
    UnknownMaterial,
    /// A polygon ear clipping could not triangulate, fanned instead.
    Fallback,
    /// A vertex colour component outside 0..1, clamped.
    Colour,
}

impl Kind {
    fn describe(self) -> &'static str {
        match self {
            Kind::Library => "material library problems",
            Kind::UnknownMaterial => "materials used but not defined",
            Kind::Fallback => "polygons fan-triangulated because ear clipping failed",
            Kind::Colour => "vertex colours outside 0..1 clamped",
        }
    }
}

#[derive(Default)]
pub(super) struct Notes {
    counts: BTreeMap<Kind, u64>,
    /// Keyword → (first line, count).
    unsupported: BTreeMap<String, (u64, u64)>,
    other_unsupported: Option<(u64, u64)>,
}

impl Notes {
    /// Passes the warning on unless enough of its kind were; `message` is built only then.
    pub(super) fn warn(
        &mut self,
        sink: &mut dyn TriangleSink,
        kind: Kind,
        at: &Location,
        message: impl FnOnce() -> String,
    ) {
        let seen = self.counts.entry(kind).or_default();
        *seen += 1;
        if *seen <= SHOWN {
            sink.warn(at, message());
        }
    }

    pub(super) fn unsupported(&mut self, keyword: &str, line: u64) {
        if let Some(entry) = self.unsupported.get_mut(keyword) {
            entry.1 += 1;
        } else if self.unsupported.len() < KEYWORDS {
            self.unsupported.insert(keyword.to_string(), (line, 1));
        } else {
            self.other_unsupported.get_or_insert((line, 0)).1 += 1;
        }
    }

    /// Reports what was held back.
    pub(super) fn finish(&self, sink: &mut dyn TriangleSink, file: &str) {
        for (keyword, &(first, count)) in &self.unsupported {
            sink.warn(
                &Location::line(file, first),
                format!("statement `{keyword}` is not supported and was skipped ({count} in all)"),
            );
        }
        if let Some((first, count)) = self.other_unsupported {
            sink.warn(
                &Location::line(file, first),
                format!("{count} more statements of other unsupported kinds were skipped"),
            );
        }
        for (&kind, &count) in &self.counts {
            if count > SHOWN {
                sink.warn(
                    &Location::file(file),
                    format!("{} more warnings: {}", count - SHOWN, kind.describe()),
                );
            }
        }
    }
}
