//! A server's `application/problem+json` answer (RFC 9457), printed field by field so that a
//! build log shows each field at fault by its JSON Pointer and why.

use serde_json::Value;

/// What a server said was wrong.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Problem {
    /// The short summary (`title`).
    pub title: Option<String>,
    /// The explanation (`detail`).
    pub detail: Option<String>,
    /// Each field at fault: its JSON Pointer and the reason.
    pub errors: Vec<(String, String)>,
    /// The body, when it is not a problem document (from a proxy, say).
    pub text: Option<String>,
    /// When to try again (`Retry-After`), if the server said.
    pub retry_after: Option<String>,
}

impl Problem {
    /// Reads a problem body; a body that is not one is kept as text.
    pub fn from_body(bytes: &[u8], retry_after: Option<String>) -> Self {
        let string = |v: &Value, key: &str| v.get(key).and_then(Value::as_str).map(str::to_string);
        match serde_json::from_slice::<Value>(bytes) {
            Ok(body) if body.is_object() => Self {
                title: string(&body, "title"),
                detail: string(&body, "detail"),
                errors: body
                    .get("errors")
                    .and_then(Value::as_array)
                    .into_iter()
                    .flatten()
                    .map(|e| {
                        (string(e, "pointer").unwrap_or_default(), string(e, "detail").unwrap_or_default())
                    })
                    .collect(),
                text: None,
                retry_after,
            },
            _ => {
                let text = String::from_utf8_lossy(bytes).trim().chars().take(2000).collect::<String>();
                Self { text: (!text.is_empty()).then_some(text), retry_after, ..Self::default() }
            }
        }
    }

    /// The lines to show: the title, then `pointer: reason` per field, or, without fields, the
    /// detail (which sums the fields up when there are some).
    pub fn lines(&self) -> Vec<String> {
        let detail = self.detail.as_ref().filter(|_| self.errors.is_empty());
        let mut lines: Vec<String> = self.title.iter().chain(detail).chain(&self.text).cloned().collect();
        lines.extend(self.errors.iter().map(|(pointer, reason)| format!("{pointer}: {reason}")));
        if let Some(seconds) = &self.retry_after {
            lines.push(format!("retry after {seconds} s"));
        }
        lines
    }

    /// Prints [`Problem::lines`] on standard error.
    pub fn print(&self) {
        self.lines().iter().for_each(|line| eprintln!("  {line}"));
    }
}

#[cfg(test)]
mod tests {
    use super::Problem;

    #[test]
    fn a_problem_body_is_shown_field_by_field() {
        let body = br#"{"type": "about:blank", "title": "Invalid scene", "status": 422,
            "detail": "the scene has 2 invalid fields",
            "errors": [{"pointer": "/dt", "detail": "must be positive, got -1"},
                       {"pointer": "/bodies/0/count", "detail": "must be at least 2, got 1"}]}"#;
        assert_eq!(
            Problem::from_body(body, None).lines(),
            ["Invalid scene", "/dt: must be positive, got -1", "/bodies/0/count: must be at least 2, got 1"]
        );
    }

    #[test]
    fn another_body_is_kept_as_text_with_its_retry_time() {
        let problem = Problem::from_body(b"<html>Bad Gateway</html>\n", Some("5".into()));
        assert_eq!(problem.lines(), ["<html>Bad Gateway</html>", "retry after 5 s"]);
        assert_eq!(Problem::from_body(b"", None).lines(), Vec::<String>::new());
        let refused = br#"{"title": "Unauthorized", "status": 401, "detail": "no bearer token"}"#;
        assert_eq!(Problem::from_body(refused, None).lines(), ["Unauthorized", "no bearer token"]);
        let refused = br#"{"title": "Unauthorized", "status": 401, "detail": "no bearer token"}"#;
        assert_eq!(Problem::from_body(refused, None).lines(), ["Unauthorized", "no bearer token"]);
    }
}
