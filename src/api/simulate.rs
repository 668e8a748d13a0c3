//! `POST /simulate`: runs a small scene through the job queue and answers with its result.
//!
//! The result is in the format `?format=` or `Accept` names, else the scene's `output.format`;
//! a format chosen here records and sends the fields it carries and names the others in
//! `Drape-Omitted-Fields`, and `?fields=` records and sends the fields it names
//! ([`SceneBody::for_result`]).
//! The job is an ordinary job (it shows in `GET /jobs`); the handler waits for it. Runs over the
//! work budget (element-steps, see [`Cost`](crate::jobs::Cost)) are refused with `413`, the
//! field of the costliest stage and a pointer to `POST /jobs`. A run that ends failed because
//! its self-collision met more pairs than it may hold is a `422` at that field. If the
//! client goes away or the request times out, the job is cancelled. The scene is compiled once,
//! at admission, and a worker of this instance runs that model (see
//! [`KeptModel`](crate::jobs::KeptModel)).

use axum::extract::State;
use axum::http::{HeaderValue, header};
use axum::response::Response;

use super::AppState;
use super::extract::{FieldsChoice, FormatChoice, SceneBody};
use super::jobs::result_response;
use super::problem::AppError;
use crate::jobs::{Failure, JobId, JobStatus, Jobs, Submission};
use crate::scene::FieldError;

/// Runs the scene and returns its result; a diverged run is a `200` with `stats.status` `diverged`.
pub async fn simulate(
    State(state): State<AppState>,
    FormatChoice(format): FormatChoice<true>,
    FieldsChoice(fields): FieldsChoice,
    body: SceneBody,
) -> Result<Response, AppError> {
    let (body, omitted) = body.for_result(format, fields)?;
    let submission = Submission {
        scene: body.scene,
        document: body.document,
        fingerprint: body.fingerprint,
        idempotency_key: None,
        max_work: Some(state.config.simulate_work_budget),
    };
    // Held until the job ends: this instance's worker runs the model admission compiled.
    let (submitted, _kept) = state.jobs.submit_to_wait(submission).await?;
    let id = submitted.job.id;
    let guard = CancelOnDrop { jobs: state.jobs.clone(), id: Some(id.clone()) };
    let ended = state
        .jobs
        .wait_with_result(&id)
        .await?
        .ok_or_else(|| AppError::Internal(format!("job {id} vanished")))?;
    guard.disarm();
    let job = ended.job;
    match job.status {
        JobStatus::Succeeded | JobStatus::Diverged => {
            let result = ended.result.ok_or_else(|| AppError::Internal(format!("job {id} has no result")))?;
            let mut response = result_response(&job, result, &omitted);
            let location = HeaderValue::from_str(&format!("/jobs/{id}")).expect("job ids are URL-safe");
            response.headers_mut().insert(header::CONTENT_LOCATION, location);
            Ok(response)
        }
        JobStatus::Cancelled => Err(AppError::JobCancelled { id, message: job.message }),
        JobStatus::Failed if job.failure == Some(Failure::Limit) => {
            Err(AppError::OverLimit(vec![FieldError::new(
                "/self_collision/thickness",
                format!(
                    "job {id} failed: {}",
                    job.message
                        .unwrap_or_else(|| "self-collision met more pairs than the run may hold".into())
                ),
            )]))
        }
        JobStatus::Failed if job.failure == Some(Failure::WallTime) => Err(AppError::TooSlow {
            id,
            message: job.message.unwrap_or_else(|| "the run exceeded the wall-time limit".into()),
        }),
        JobStatus::Failed | JobStatus::Queued | JobStatus::Running => Err(AppError::JobFailed {
            id,
            message: job.message.unwrap_or_else(|| format!("ended {}", job.status.name())),
        }),
    }
}

/// Cancels the job if the request is dropped before it ends.
struct CancelOnDrop {
    jobs: Jobs,
    id: Option<JobId>,
}

impl CancelOnDrop {
    fn disarm(mut self) {
        self.id = None;
    }
}

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        if let Some(id) = self.id.take() {
            let jobs = self.jobs.clone();
            tokio::spawn(async move {
                tracing::info!(job = %id, "the client left; cancelling its /simulate job");
                let _ = jobs.cancel(&id).await;
            });
        }
    }
}
