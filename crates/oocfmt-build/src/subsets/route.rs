//! Reading the inputs for a plan or a subset: every pass imports every input through the same
//! intake as `convert`, so materials, parts and dropped triangles are numbered alike in every
//! process; what differs is the store behind it.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::plan::{Plan, SubsetCell};
use super::SubsetError;
use crate::convert::{import_one, ConvertOptions};
use crate::interrupt::WatchedSink;
use crate::ooc::disk::SpillDisk;
use crate::ooc::segments::Run;
use crate::ooc::soup::{SoupTriangle, SoupWriter, Tally};
use crate::ooc::split::{Cut, Sides, TopNode};
use crate::progress::Progress;
use oocfmt_meshio::import::{ImportError, InputTriangle, Intake, Intaken, Location, Store};

/// Imports every input, in order, into an intake in front of `store`, as `convert` would:
/// positions relative to `origin`, each file a part when there are several. `on_input` is
/// told the store and each input's index before it is read.
pub(super) fn import_all<S: Store>(
    inputs: &[PathBuf],
    store: S,
    origin: [f64; 3],
    opts: &ConvertOptions,
    phase: &str,
    progress: &mut dyn Progress,
    mut on_input: impl FnMut(&mut S, usize),
) -> Result<Intaken<S>, SubsetError> {
    let mut sink = Intake::with_store(opts.strict, store)
        .with_origin(origin)
        .with_file_parts(inputs.len() > 1);
    progress.phase(phase, Some(inputs.len() as u64));
    for (i, path) in inputs.iter().enumerate() {
        on_input(sink.store_mut(), i);
        import_one(
            path,
            &mut WatchedSink::new(&mut sink, &opts.interrupt),
            opts,
        )
        .map_err(Box::new)?;
        progress.advance(i as u64 + 1);
    }
    progress.finish_phase();
    Ok(sink.finish_intake()?)
}

/// A subset's store: keeps the copy of each triangle that reaches its cell, routed down the
/// plan's cuts as the out-of-core split routes it, primary where the split would make it so.
pub(super) struct CellStore {
    path: Vec<(Cut, bool)>,
    writer: SoupWriter,
    pub tally: Tally,
}

impl CellStore {
    /// A store for `cell` of `plan`, spilling to a run named after `base`.
    pub fn new(
        plan: &Plan,
        tree: &[TopNode],
        cell: &SubsetCell,
        base: &Path,
        disk: Arc<SpillDisk>,
    ) -> Result<CellStore, SubsetError> {
        let mut path = Vec::new();
        let mut at = plan.scene_bounds();
        for (&a, &low) in cell.ancestors.iter().zip(&cell.sides) {
            let Some(&TopNode::Inner { axis, split, .. }) = tree.get(a) else {
                return Err(SubsetError::Internal("a cell's ancestor is not a cut"));
            };
            let cut = Cut {
                cell: at,
                axis: usize::from(axis),
                mid: split,
            };
            let (lo, hi) = at.split(cut.axis, split);
            at = if low { lo } else { hi };
            path.push((cut, low));
        }
        Ok(CellStore {
            path,
            writer: SoupWriter::create(base, disk),
            tally: Tally::default(),
        })
    }

    /// Flushes the cell's run.
    pub fn finish(self) -> Result<Run, SubsetError> {
        Ok(self.writer.finish()?)
    }
}

impl Store for CellStore {
    fn store(&mut self, t: InputTriangle, _at: &Location) -> Result<(), ImportError> {
        self.tally.add(&t);
        let mut copy = SoupTriangle {
            triangle: t,
            primary: true,
        };
        for (cut, low) in &self.path {
            match Sides::of(&copy, cut).copy(&copy, *low) {
                Some(c) => copy = c,
                None => return Ok(()),
            }
        }
        self.writer.push(&copy).map_err(|e| ImportError::Io {
            path: self.writer.base().display().to_string(),
            source: std::io::Error::new(e.io_kind(), e.to_string()),
        })
    }
}
