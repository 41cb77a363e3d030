//! Built physics kept by model and exact parameter bits.
//!
//! Building the bound (its supremum needs an integration to convergence) is by far the most
//! expensive part of an instance, and fmi2Reset, fmi2SetFMUstate and the fresh instances of a
//! parameter sweep build the same plant again and again. Building is deterministic, so a copy
//! steps bit-identically to a new build.

use std::sync::Mutex;

use super::adapter::Values;
use super::error::FmuError;
use super::variables::{Causality, ModelInfo};

/// How many parameter sets keep their built physics, per kind of physics.
const KEPT: usize = 8;

type Key = (&'static str, Vec<u64>);

/// The last [`KEPT`] parameter sets' built physics of one kind (a single gap's simulation, a
/// gearbox's).
pub struct Templates<T> {
    built: Mutex<Vec<(Key, T)>>,
}

impl<T: Clone> Templates<T> {
    pub const fn new() -> Templates<T> {
        Templates {
            built: Mutex::new(Vec::new()),
        }
    }

    /// A copy of what `build` made for `model` at the parameter values of `v`: kept from an
    /// earlier call with the same values, else built now (outside the lock: other instances need
    /// not wait for it) and kept. An error is returned, not kept.
    pub fn get(
        &self,
        model: &ModelInfo,
        v: &Values,
        build: impl FnOnce() -> Result<T, FmuError>,
    ) -> Result<T, FmuError> {
        let key: Key = (
            model.identifier,
            model
                .variables
                .iter()
                .filter(|var| var.causality == Causality::Parameter)
                .map(|var| v[var.symbol.index()].to_bits())
                .collect(),
        );
        let lock = || self.built.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Some((_, built)) = lock().iter().find(|(k, _)| *k == key) {
            return Ok(built.clone());
        }
        let built = build()?;
        let mut kept = lock();
        if kept.len() == KEPT {
            kept.remove(0);
        }
        kept.push((key, built.clone()));
        Ok(built)
    }
}

impl<T: Clone> Default for Templates<T> {
    fn default() -> Templates<T> {
        Templates::new()
    }
}
