//! Server-sent events (the `text/event-stream` of `GET /jobs/{id}/events` and
//! `GET /sweeps/{id}/events`), read one event at a time from a byte stream as the HTML standard
//! defines them: `event:` and `data:` lines, comments (`:`) skipped, a blank line ending each
//! event; and [`follow`], which reads such a stream from the server to its `end` event.

use std::io::{self, BufRead, BufReader, Read};

use serde_json::Value;

use super::Server;

/// Follows the events at `target` on `server`: the data of each `progress` event goes to
/// `progress`, and the data of the `end` event is returned if `ended` accepts it. `None` if the
/// stream cannot be opened, or stops (an `error` event, an `end` that `ended` does not accept, a
/// stream cut short) before: the caller then looks for the end itself.
pub fn follow(
    server: &Server,
    target: &str,
    progress: impl Fn(&Value),
    ended: impl Fn(&Value) -> bool,
) -> Option<Value> {
    let stream = server.get(target, "text/event-stream").ok()?;
    for event in Events::new(stream.into_body().into_reader()) {
        let event = event.ok()?;
        let Ok(data) = serde_json::from_str::<Value>(&event.data) else { continue };
        match event.name.as_str() {
            "progress" => progress(&data),
            "end" if ended(&data) => return Some(data),
            "end" | "error" => return None,
            _ => {}
        }
    }
    None
}

/// One event: its name (`message` when none is given) and its data lines, joined by `\n`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Event {
    /// The `event:` field.
    pub name: String,
    /// The `data:` fields.
    pub data: String,
}

/// The events of a stream, in order; an event cut off by the end of the stream is dropped.
pub struct Events<R> {
    reader: BufReader<R>,
}

impl<R: Read> Events<R> {
    /// Reads events from `stream`.
    pub fn new(stream: R) -> Self {
        Self { reader: BufReader::new(stream) }
    }
}

impl<R: Read> Iterator for Events<R> {
    type Item = io::Result<Event>;

    fn next(&mut self) -> Option<Self::Item> {
        let (mut name, mut data): (Option<String>, Option<String>) = (None, None);
        let mut line = String::new();
        loop {
            line.clear();
            match self.reader.read_line(&mut line) {
                Ok(0) => return None,
                Ok(_) => {}
                Err(e) => return Some(Err(e)),
            }
            let line = line.trim_end_matches(['\n', '\r']);
            if line.is_empty() {
                if let Some(data) = data.take() {
                    return Some(Ok(Event { name: name.unwrap_or_else(|| "message".into()), data }));
                }
                name = None;
                continue;
            }
            let (field, value) = line.split_once(':').unwrap_or((line, ""));
            let value = value.strip_prefix(' ').unwrap_or(value);
            match field {
                "event" => name = Some(value.to_string()),
                "data" => match &mut data {
                    Some(data) => {
                        data.push('\n');
                        data.push_str(value);
                    }
                    None => data = Some(value.to_string()),
                },
                _ => {} // comments (an empty field name), `id:`, `retry:`
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{Event, Events};

    #[test]
    fn events_are_read_as_the_standard_defines_them() {
        let stream = ": keep-alive\n\nevent: progress\ndata: {\"step\": 5}\n\ndata: a\ndata:b\r\n\r\n\
                      event: end\nid: 7\ndata: {}\n\nevent: cut\ndata: off";
        let events: Vec<Event> = Events::new(stream.as_bytes()).map(Result::unwrap).collect();
        assert_eq!(
            events,
            [
                Event { name: "progress".into(), data: "{\"step\": 5}".into() },
                Event { name: "message".into(), data: "a\nb".into() },
                Event { name: "end".into(), data: "{}".into() },
            ]
        );
    }
}
