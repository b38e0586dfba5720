//! The training environment as `risktwin train` steps it: `n` driving environments in
//! flat buffers, stepped in parallel (rayon) with the GIL released, auto-reset in the same
//! step (Gymnasium's `SAME_STEP` mode) with the final observation kept apart.

use crate::error::{bad_input, failed};
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use risktwin_common::env::{ACT_DIM, OBS_DIM, RiskShaping, ScenarioSource, Variant};
use risktwin_common::scenario::ScenarioKind;
use risktwin_learn::train::training_source;

/// What one step gives back: observations, rewards, terminated, truncated, final observations.
type StepArrays<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray2<f32>>,
);

/// `n` environments of one variant drawing scenarios of one kind or of all five.
#[pyclass(module = "risktwin._native")]
pub struct VecEnv {
    env: risktwin_common::env::VecEnv,
    n: usize,
    kind: Option<ScenarioKind>,
    variant: Variant,
    /// The last step's actions, copied out of the caller's array (reused: no allocation).
    actions: Vec<f32>,
}

impl VecEnv {
    /// The scenario stream of `seed`: the trainer's for all kinds (for `full`, its replay of
    /// the risk-ranked list beside fresh samples), else fresh samples of `kind`.
    fn source(kind: Option<ScenarioKind>, variant: Variant, seed: u64) -> ScenarioSource {
        match kind {
            None => training_source(variant, seed),
            Some(kind) => ScenarioSource::Sampled { seed, kinds: vec![kind] },
        }
    }

    fn build(py: Python<'_>, n: usize, kind: Option<ScenarioKind>, variant: Variant, seed: u64) -> PyResult<Self> {
        let env = py.detach(|| {
            let reward = variant.training_reward(RiskShaping::default());
            risktwin_common::env::VecEnv::new(n, Self::source(kind, variant, seed), reward)
        });
        Ok(Self { env: env.map_err(failed)?, n, kind, variant, actions: vec![0.0; n * ACT_DIM] })
    }

    fn rows<'py>(&self, py: Python<'py>, flat: &[f32], width: usize) -> PyResult<Bound<'py, PyArray2<f32>>> {
        PyArray1::from_slice(py, flat).reshape([self.n, width])
    }
}

#[pymethods]
impl VecEnv {
    /// `n` environments (1 to 65,536) of `variant` (base, risk-only, full, ttc) on scenarios
    /// of `kind` (None: all five, as the trainer samples them), the stream of `seed`.
    #[new]
    #[pyo3(signature = (n, *, kind = None, variant = "full", seed = 0))]
    fn new(py: Python<'_>, n: usize, kind: Option<&str>, variant: &str, seed: u64) -> PyResult<Self> {
        if !(1..=MAX_ENVS).contains(&n) {
            return Err(bad_input(format!("n = {n} environments is out of range [1, {MAX_ENVS}]")));
        }
        let kind = kind.map(str::parse::<ScenarioKind>).transpose().map_err(bad_input)?;
        let variant = variant.parse::<Variant>().map_err(bad_input)?;
        Self::build(py, n, kind, variant, seed)
    }

    #[getter]
    fn num_envs(&self) -> usize {
        self.n
    }

    /// The current observations, `(n, 24)` float32 (a fresh array).
    fn obs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.rows(py, self.env.obs(), OBS_DIM)
    }

    /// With a seed: every environment from the first episode of that seed's stream. Without:
    /// every environment abandons its episode and starts its next one. Returns the
    /// observations.
    #[pyo3(signature = (seed = None))]
    fn reset<'py>(&mut self, py: Python<'py>, seed: Option<u64>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        match seed {
            Some(seed) => *self = Self::build(py, self.n, self.kind, self.variant, seed)?,
            None => {
                let env = &mut self.env;
                py.detach(|| env.restart()).map_err(failed)?;
            }
        }
        self.obs(py)
    }

    /// Steps every environment with its row of `actions` (`(n, 3)` float32, each in [−1, 1]:
    /// steering, throttle, brake; outside is clamped, NaN is 0). Returns fresh arrays
    /// `(obs, rewards, terminated, truncated, final_obs)`; where an episode ended, `obs` is
    /// the next episode's first observation and `final_obs` the one that ended it.
    fn step<'py>(&mut self, py: Python<'py>, actions: PyReadonlyArray2<'py, f32>) -> PyResult<StepArrays<'py>> {
        let shape = actions.shape();
        if shape != [self.n, ACT_DIM] {
            return Err(bad_input(format!("actions have shape {shape:?}, not [{}, {ACT_DIM}]", self.n)));
        }
        // A non-contiguous view is copied element by element.
        match actions.as_slice() {
            Ok(flat) => self.actions.copy_from_slice(flat),
            Err(_) => self.actions.iter_mut().zip(actions.as_array().iter()).for_each(|(a, &v)| *a = v),
        }
        let (env, acts) = (&mut self.env, &self.actions);
        py.detach(|| env.step(acts)).map_err(failed)?;
        let flags = |f: &[u8]| PyArray1::from_iter(py, f.iter().map(|&x| x != 0));
        Ok((
            self.rows(py, self.env.obs(), OBS_DIM)?,
            PyArray1::from_slice(py, self.env.rewards()),
            flags(self.env.terminated()),
            flags(self.env.truncated()),
            self.rows(py, self.env.final_obs(), OBS_DIM)?,
        ))
    }

    /// The episodes the last step finished: `(index, kind, metrics as JSON)` in environment
    /// order. Only what the training environment measures: its episodes compute no risk score,
    /// time-to-collision or closest distance (an evaluation does).
    fn finished(&mut self) -> Vec<(usize, &'static str, String)> {
        let mut done = Vec::new();
        self.env.drain_finished(|i, s| {
            let m = &s.metrics;
            let metrics = serde_json::json!({
                "ended": m.ending(),
                "collision": m.collision,
                "offroad": m.offroad,
                "success": m.success,
                "route_completion": m.route_completion,
                "avg_speed_mps": m.avg_speed_mps,
                "steering_smoothness": m.steering_smoothness,
                "longitudinal_smoothness": m.longitudinal_smoothness,
                "reward": m.reward,
                "steps": m.steps,
            });
            done.push((i, s.kind.name(), metrics.to_string()));
        });
        done
    }
}

/// Environment steps per second of `n` native environments stepped `steps` times with the
/// zero action and no Python in the loop: the raw path the Python-side loop of
/// python/bench/speed.py is measured against, in the same process.
#[pyfunction]
#[pyo3(signature = (n, steps, *, variant = "full", seed = 0))]
pub fn native_steps_per_s(py: Python<'_>, n: usize, steps: usize, variant: &str, seed: u64) -> PyResult<f64> {
    if !(1..=MAX_MEASURED_STEPS).contains(&steps) {
        return Err(bad_input(format!("steps = {steps} is out of range [1, {MAX_MEASURED_STEPS}]")));
    }
    let mut env = VecEnv::new(py, n, None, variant, seed)?;
    let actions = vec![0.0f32; n * ACT_DIM];
    py.detach(|| {
        let started = std::time::Instant::now();
        for _ in 0..steps {
            env.env.step(&actions)?;
        }
        Ok::<_, risktwin_common::env::SourceError>(n as f64 * steps as f64 / started.elapsed().as_secs_f64())
    })
    .map_err(failed)
}

/// The most environments one vector holds.
pub const MAX_ENVS: usize = 65_536;

/// Environment steps one [`native_rollout`] may record (its observations: 400 MB).
const MAX_ROLLOUT_CELLS: usize = 1 << 22;

/// Steps one [`native_steps_per_s`] measurement may take.
const MAX_MEASURED_STEPS: usize = 100_000;

/// What [`native_rollout`] gives back: every step's observations, rewards, terminated, truncated.
type Rollout<'py> =
    (Bound<'py, PyArray3<f32>>, Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<bool>>, Bound<'py, PyArray2<bool>>);

/// The native vector of environments stepped with `actions` (`(steps, n, 3)` float32,
/// C-contiguous) from the stream of `seed`, every step in Rust with no Python between them:
/// `(obs (steps, n, 24), rewards, terminated, truncated (steps, n))`, what `DrivingVecEnv`
/// must give step for step (python/tests/test_envs.py).
#[pyfunction]
#[pyo3(signature = (actions, *, kind = None, variant = "full", seed = 0))]
pub fn native_rollout<'py>(
    py: Python<'py>,
    actions: PyReadonlyArray3<'py, f32>,
    kind: Option<&str>,
    variant: &str,
    seed: u64,
) -> PyResult<Rollout<'py>> {
    let (steps, n, width) = (actions.shape()[0], actions.shape()[1], actions.shape()[2]);
    if width != ACT_DIM {
        return Err(bad_input(format!("actions have {width} columns, not {ACT_DIM}")));
    }
    let cells = steps.checked_mul(n).filter(|&c| c <= MAX_ROLLOUT_CELLS);
    let Some(cells) = cells.filter(|&c| c > 0) else {
        return Err(bad_input(format!("{steps} steps x {n} environments is out of range [1, {MAX_ROLLOUT_CELLS}]")));
    };
    // Copied while the GIL is held: another thread may write the caller's array meanwhile.
    let flat = actions.as_slice().map_err(|_| bad_input("actions must be a C-contiguous array"))?.to_vec();
    let mut env = VecEnv::new(py, n, kind, variant, seed)?;
    let (mut obs, mut rewards) = (Vec::with_capacity(cells * OBS_DIM), Vec::with_capacity(cells));
    let (mut terminated, mut truncated) = (Vec::with_capacity(cells), Vec::with_capacity(cells));
    py.detach(|| {
        for step in flat.chunks_exact(n * ACT_DIM) {
            env.env.step(step)?;
            obs.extend_from_slice(env.env.obs());
            rewards.extend_from_slice(env.env.rewards());
            terminated.extend(env.env.terminated().iter().map(|&x| x != 0));
            truncated.extend(env.env.truncated().iter().map(|&x| x != 0));
        }
        Ok::<_, risktwin_common::env::SourceError>(())
    })
    .map_err(failed)?;
    Ok((
        PyArray1::from_vec(py, obs).reshape([steps, n, OBS_DIM])?,
        PyArray1::from_vec(py, rewards).reshape([steps, n])?,
        PyArray1::from_vec(py, terminated).reshape([steps, n])?,
        PyArray1::from_vec(py, truncated).reshape([steps, n])?,
    ))
}
