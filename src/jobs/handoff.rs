//! Models compiled at admission, handed on to this instance's worker so the run does not compile
//! its scene a second time.
//!
//! Admission compiles a scene to plan it (its steps come from the built model's stability bound
//! and its self-collision cost from the built particles). A queued job (`POST /jobs`) may run
//! on any instance sharing the store, days later, so its model is not kept: the worker compiles
//! the stored scene. A job whose submitter waits for it here (`POST /simulate`) keeps its model
//! in the [`Handoff`] for as long as its [`KeptModel`] lives; the worker of this instance that
//! claims it takes the model instead of compiling the stored scene again, which gives the same
//! model: the same scene admitted under the same limits. A worker of another instance compiles
//! as usual. At most one model per worker is kept, so the models held for jobs not yet running
//! stay bounded whatever the queue holds.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use super::id::JobId;
use crate::scene::Compiled;

/// The models kept for jobs queued here, by job.
pub(super) struct Handoff {
    models: Mutex<HashMap<JobId, Compiled>>,
    most: usize,
}

impl Handoff {
    /// Room for `most` models.
    pub(super) fn new(most: usize) -> Self {
        Self { models: Mutex::new(HashMap::new()), most: most.max(1) }
    }

    fn models(&self) -> MutexGuard<'_, HashMap<JobId, Compiled>> {
        self.models.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Keeps `compiled` for the worker that claims job `id`, if there is room; the model is
    /// forgotten when the returned [`KeptModel`] is dropped, unless a worker took it first.
    pub(super) fn keep(self: &Arc<Self>, id: &JobId, compiled: Compiled) -> KeptModel {
        let mut models = self.models();
        if models.len() >= self.most {
            return KeptModel::NONE;
        }
        models.insert(id.clone(), compiled);
        KeptModel { kept: Some((Arc::clone(self), id.clone())) }
    }

    /// The model kept for job `id`, taken out: the worker that claimed it runs it.
    pub(super) fn take(&self, id: &JobId) -> Option<Compiled> {
        self.models().remove(id)
    }

    /// Whether a model is kept for job `id`.
    #[cfg(test)]
    pub(super) fn holds(&self, id: &JobId) -> bool {
        self.models().contains_key(id)
    }
}

/// A job's model kept for this instance's workers (see the [module](self)): hold it while
/// waiting for the job, and drop it after; dropping it forgets a model no worker took.
#[must_use = "the kept model is forgotten as soon as this is dropped"]
pub struct KeptModel {
    kept: Option<(Arc<Handoff>, JobId)>,
}

impl KeptModel {
    /// Nothing kept.
    pub(super) const NONE: Self = Self { kept: None };
}

impl Drop for KeptModel {
    fn drop(&mut self) {
        if let Some((handoff, id)) = self.kept.take() {
            handoff.take(&id);
        }
    }
}

impl std::fmt::Debug for KeptModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("KeptModel").field("job", &self.kept.as_ref().map(|(_, id)| id)).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    fn model() -> Compiled {
        Scene::from_json(br#"{"duration": 1, "bodies": [{"type": "chain", "count": 3}]}"#).unwrap().compile()
    }

    #[test]
    fn a_worker_takes_a_kept_model_once() {
        let handoff = Arc::new(Handoff::new(2));
        let id = JobId::new();
        let kept = handoff.keep(&id, model());
        assert!(handoff.holds(&id));
        assert_eq!(handoff.take(&id).map(|c| c.model.particle_count()), Some(3));
        assert!(handoff.take(&id).is_none(), "a second claim compiles the stored scene");
        drop(kept);
    }

    #[test]
    fn dropping_the_kept_model_forgets_it() {
        let handoff = Arc::new(Handoff::new(2));
        let id = JobId::new();
        drop(handoff.keep(&id, model()));
        assert!(!handoff.holds(&id));
    }

    #[test]
    fn no_more_models_than_workers_are_kept() {
        let handoff = Arc::new(Handoff::new(1));
        let (first, second) = (JobId::new(), JobId::new());
        let _kept = handoff.keep(&first, model());
        let _not_kept = handoff.keep(&second, model());
        assert!(handoff.holds(&first));
        assert!(!handoff.holds(&second), "the second job's worker compiles its scene");
    }
}
