//! The JSON shape of a job as the API shows it.

use serde_json::{Value, json};

use crate::jobs::JobRecord;

/// A job as `GET /jobs/{id}` shows it.
pub fn job_view(job: &JobRecord) -> Value {
    let id = &job.id;
    let mut view = json!({
        "id": id.as_str(),
        "status": job.status.name(),
        "created_at": rfc3339(job.created_ms),
        "progress": progress(job),
        "particles": job.plan.particles,
        "springs": job.plan.springs,
        "attempts": job.attempts,
        "links": {
            "self": format!("/jobs/{id}"),
            "result": format!("/jobs/{id}/result"),
            "events": format!("/jobs/{id}/events"),
        },
    });
    if let Some(ms) = job.started_ms {
        view["started_at"] = rfc3339(ms).into();
    }
    if let Some(ms) = job.finished_ms {
        view["finished_at"] = rfc3339(ms).into();
    }
    if let Some(message) = &job.message {
        view["message"] = message.clone().into();
    }
    if let Some(failure) = job.failure {
        view["failure"] = failure.name().into();
    }
    if let Some(stats) = &job.stats {
        view["stats"] = stats.clone();
    }
    view
}

/// Steps taken, of how many, the simulated time reached and the fraction done.
pub fn progress(job: &JobRecord) -> Value {
    let plan = &job.plan;
    let fraction = if plan.steps == 0 { 1.0 } else { job.steps_done as f64 / plan.steps as f64 };
    json!({
        "step": job.steps_done,
        "steps": plan.steps,
        "t": (job.steps_done as f64 * plan.dt).min(plan.duration),
        "fraction": fraction.min(1.0),
    })
}

/// Milliseconds since the Unix epoch as an RFC 3339 UTC timestamp, e.g. `2026-11-22T03:50:29.123Z`.
pub fn rfc3339(ms: u64) -> String {
    let (days, ms_of_day) = (ms / 86_400_000, ms % 86_400_000);
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    let (h, m, s, milli) =
        (ms_of_day / 3_600_000, ms_of_day / 60_000 % 60, ms_of_day / 1000 % 60, ms_of_day % 1000);
    format!("{year:04}-{month:02}-{day:02}T{h:02}:{m:02}:{s:02}.{milli:03}Z")
}

#[cfg(test)]
mod tests {
    use super::rfc3339;

    #[test]
    fn timestamps_match_known_dates() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(rfc3339(951_782_400_000), "2000-02-29T00:00:00.000Z");
        assert_eq!(rfc3339(1_700_000_000_123), "2023-11-14T22:13:20.123Z");
        assert_eq!(rfc3339(4_102_444_799_999), "2099-12-31T23:59:59.999Z");
    }
}
