//! Server-sent events (the `text/event-stream` of `GET /jobs/{id}/events`), read one event at a
//! time from a byte stream as the HTML standard defines them: `event:` and `data:` lines,
//! comments (`:`) skipped, a blank line ending each event.

use std::io::{self, BufRead, BufReader, Read};

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
