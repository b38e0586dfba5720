//! Why a run stopped. Each variant says whose fault it was ([`RunError::is_input`]), so the
//! binary can keep docs/cli.md's exit codes (2 for bad input, 1 for a runtime failure).

use risktwin_cloud::trainer::TrainerError;
use risktwin_store::library::LibraryError;
use std::path::PathBuf;

/// Why `risktwin run` failed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A file or folder of the report could not be created.
    #[error("cannot create {}: {source}", path.display())]
    Create { path: PathBuf, source: std::io::Error },
    /// The report folder holds a library already: a run never writes over another.
    #[error("{} already exists; choose a fresh --out", path.display())]
    UsedOutDir { path: PathBuf },
    #[error(transparent)]
    Library(#[from] LibraryError),
    #[error(transparent)]
    Trainer(#[from] TrainerError),
    #[error(transparent)]
    Learn(#[from] risktwin_learn::LearnError),
    /// A risk-field snapshot of a top scenario.
    #[error(transparent)]
    Field(#[from] risktwin_common::risk::FieldError),
    #[error(transparent)]
    Recording(#[from] risktwin_cloud::episode_recording::EpisodeRecordingError),
    /// A file the run wrote could not be read back.
    #[error("cannot read {}: {source}", path.display())]
    Read { path: PathBuf, source: std::io::Error },
    /// A file of the report could not be written.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// A figure could not be drawn or written.
    #[error(transparent)]
    Figure(#[from] crate::figures::FigureError),
    /// The closed loop over Zenoh.
    #[error(transparent)]
    ClosedLoop(#[from] crate::push_loop::LoopError),
    /// The run was asked to stop.
    #[error("the run was stopped")]
    Stopped,
}

impl RunError {
    /// Whether the input (flags, config, report folder) was at fault rather than the run.
    pub fn is_input(&self) -> bool {
        matches!(
            self,
            RunError::Create { .. }
                | RunError::UsedOutDir { .. }
                | RunError::Figure(crate::figures::FigureError::Create { .. })
        )
    }
}
