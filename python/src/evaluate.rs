//! `risktwin.evaluate`: a driver SPEC (`idm`, `PATH.safetensors`, `PATH.onnx`) or a Python
//! callable `obs -> action` over the held-out set of a run seed or over a library's generated
//! scenarios, beside the reference driver: the document of `risktwin evaluate --format json`,
//! built by the same code ([`risktwin_cloud::trainer::evaluation`]).

use crate::error::{bad_input, failed};
use numpy::PyArray1;
use pyo3::prelude::*;
use risktwin_cloud::generate::worker_threads;
use risktwin_cloud::trainer::HeldOut;
use risktwin_cloud::trainer::drive::{Driver, EVAL_VARIANT};
use risktwin_cloud::trainer::evaluation::{
    DEFAULT_PER_KIND, DEFAULT_SEED, Driven, EvaluationDoc, MAX_PER_KIND, ScenarioSet, avoidable, library_specs,
    reference_runs, store_outcomes,
};
use risktwin_common::env::{ACT_DIM, OBS_DIM, ObsPolicy};
use risktwin_common::episode::{self, EpisodeResult};
use risktwin_common::scenario::{ScenarioSpec, build};
use risktwin_policy::model::ModelFile;
use risktwin_policy::spec::{self, DriverSpec};
use risktwin_store::library::{LibraryError, ScenarioLibrary};
use std::path::PathBuf;

/// Who drives: a model file (or the reference driver) or a Python callable.
enum Candidate<'py> {
    Spec { label: String, model: Option<ModelFile> },
    Callable(Bound<'py, PyAny>),
}

/// Evaluates `driver` and returns the document as JSON text (the Python side loads it).
#[pyfunction]
#[pyo3(signature = (driver, *, seed = None, per_kind = None, library = None, floor = false, threads = None, label = None))]
#[allow(clippy::too_many_arguments)] // The keyword arguments of `risktwin evaluate`'s flags.
pub fn evaluate(
    py: Python<'_>,
    driver: &Bound<'_, PyAny>,
    seed: Option<u64>,
    per_kind: Option<u64>,
    library: Option<PathBuf>,
    floor: bool,
    threads: Option<u64>,
    label: Option<String>,
) -> PyResult<String> {
    if library.is_some() && (seed.is_some() || per_kind.is_some()) {
        return Err(bad_input("seed and per_kind choose the held-out set; with a library its scenarios are driven"));
    }
    let (seed, per_kind) = (seed.unwrap_or(DEFAULT_SEED), per_kind.unwrap_or(DEFAULT_PER_KIND));
    if !(1..=MAX_PER_KIND).contains(&per_kind) {
        return Err(bad_input(format!("per_kind = {per_kind} is out of range [1, {MAX_PER_KIND}]")));
    }
    let threads = worker_threads(threads).map_err(|e| bad_input(format!("threads = {e}")))?;
    let candidate = candidate(driver, label.as_deref(), library.is_some())?;
    let mut lib = library.as_deref().map(open_library).transpose()?;
    let (specs, set) = match (&lib, &library) {
        (Some(lib), Some(path)) => {
            (library_specs(lib).map_err(failed)?, ScenarioSet::Library { db: path.display().to_string() })
        }
        _ => (HeldOut::new(seed, per_kind as usize).specs, ScenarioSet::HeldOut { seed, per_kind }),
    };
    if specs.is_empty() {
        return Err(bad_input("the library holds no generated scenarios to evaluate on"));
    }
    let (label, runs, faults) = match &candidate {
        Candidate::Spec { label, model } => {
            let driver = model.as_ref().map_or(Driver::Reference, |m| Driver::Model(&m.model));
            let runs = py.detach(|| driver.episodes(&specs, threads));
            (label.clone(), runs, model.as_ref().map_or(0, |m| m.model.faults()))
        }
        Candidate::Callable(f) => {
            let mut faults = 0;
            let runs = specs.iter().map(|s| drive_callable(py, f, s, &mut faults)).collect::<PyResult<Vec<_>>>()?;
            (callable_label(f, label.as_deref())?, runs, faults)
        }
    };
    let reference = py.detach(|| reference_runs(&specs, threads));
    let avoidable = floor.then(|| py.detach(|| avoidable(&specs, &reference, threads)));
    if let Some(lib) = lib.as_mut() {
        store_outcomes(lib, &specs, &runs, &label).map_err(failed)?;
    }
    let driven = Driven::generated(&specs, runs, reference);
    let doc = EvaluationDoc::new(label, set, &driven, avoidable.as_deref(), faults);
    serde_json::to_string(&doc).map_err(failed)
}

/// The driver argument: a SPEC string (its model file checked in full) or a callable.
fn candidate<'py>(driver: &Bound<'py, PyAny>, label: Option<&str>, stores: bool) -> PyResult<Candidate<'py>> {
    if let Ok(text) = driver.extract::<String>() {
        if label.is_some() {
            return Err(bad_input("label names a callable; a SPEC's label is its file's path and digest"));
        }
        let spec = text.parse::<DriverSpec>().map_err(bad_input)?;
        if spec == DriverSpec::Replay {
            return Err(bad_input(spec::REPLAY_OFF_RECORDING));
        }
        let model = spec.load().map_err(bad_input)?;
        let label = model.as_ref().map_or_else(|| spec::REFERENCE.to_owned(), ModelFile::label);
        return Ok(Candidate::Spec { label, model });
    }
    if !driver.is_callable() {
        return Err(bad_input("driver must be a SPEC (idm, PATH.safetensors, PATH.onnx) or a callable obs -> action"));
    }
    if stores && label.is_none() {
        return Err(bad_input("a callable's outcomes are stored in the library under a label: pass label=..."));
    }
    Ok(Candidate::Callable(driver.clone()))
}

/// `label`, or `python:` and the callable's qualified name.
fn callable_label(f: &Bound<'_, PyAny>, label: Option<&str>) -> PyResult<String> {
    if let Some(label) = label {
        if label.is_empty() || label == spec::REFERENCE || label == spec::REPLAY {
            return Err(bad_input(format!("label '{label}' is empty or names a built-in driver")));
        }
        return Ok(label.to_owned());
    }
    let name = f.getattr("__qualname__").or_else(|_| f.get_type().getattr("__qualname__"))?;
    Ok(format!("python:{}", name.extract::<String>()?))
}

/// One episode of `spec` driven by the callable through the training environment's
/// observation and action mapping, scored as every evaluation scores (so the metrics are
/// those of a model file giving the same actions). A decision with a non-finite number drives
/// as the zero action and is counted in `faults`, as a model's is (`risktwin_policy::onnx`).
/// The first exception ends the evaluation.
fn drive_callable(
    py: Python<'_>,
    f: &Bound<'_, PyAny>,
    spec: &ScenarioSpec,
    faults: &mut u64,
) -> PyResult<EpisodeResult> {
    let mut world = build(spec);
    let mut error: Option<PyErr> = None;
    let act = |obs: &[f32; OBS_DIM]| -> [f32; ACT_DIM] {
        if error.is_some() {
            return [0.0; ACT_DIM];
        }
        match call(py, f, obs) {
            Ok(action) if action.iter().all(|x| x.is_finite()) => action.map(|x| x.clamp(-1.0, 1.0) as f32),
            Ok(_) => {
                *faults += 1;
                [0.0; ACT_DIM]
            }
            Err(e) => {
                error = Some(e);
                [0.0; ACT_DIM]
            }
        }
    };
    let mut policy = ObsPolicy::new(act, world.desired_speed_mps, world.dt_s);
    let result = episode::run(&mut world, &mut policy, &EVAL_VARIANT.weights());
    drop(policy);
    error.map_or(Ok(result), Err)
}

/// `f(obs)` with a fresh float32 array; three numbers back, finite or not (read as Python's
/// floats: a finite number beyond float32's range is clamped, not made infinite).
fn call(py: Python<'_>, f: &Bound<'_, PyAny>, obs: &[f32; OBS_DIM]) -> PyResult<[f64; ACT_DIM]> {
    py.check_signals()?;
    let out = f.call1((PyArray1::from_slice(py, obs),))?;
    let values: Vec<f64> = out.extract().map_err(|_| bad_input("the driver must return 3 numbers"))?;
    values
        .try_into()
        .map_err(|v: Vec<f64>| bad_input(format!("the driver returned {} numbers, not {ACT_DIM}", v.len())))
}

/// A library that exists (opening creates a missing file, which an evaluation must not).
pub fn open_library(path: &std::path::Path) -> PyResult<ScenarioLibrary> {
    ScenarioLibrary::open_existing(path).map_err(library_error)
}

/// A library error: the file's fault is bad input, anything else a failed run.
pub fn library_error(e: LibraryError) -> PyErr {
    if e.blames_the_file() { bad_input(e) } else { failed(e) }
}
