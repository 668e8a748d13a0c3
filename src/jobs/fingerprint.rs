//! A stable fingerprint of a scene document, to tell a repeated request from a different one
//! under the same `Idempotency-Key`.
//!
//! The document is serialized canonically (object keys sorted at every level, no whitespace), so
//! the same scene sent with other spacing or key order has the same fingerprint; the bytes are hashed with
//! 64-bit FNV-1a, which is the same in every process and on every machine, as a shared database
//! store needs.

use serde_json::Value;

/// The fingerprint of a parsed JSON document.
pub fn fingerprint(document: &Value) -> u64 {
    fnv1a(&serde_json::to_vec(&canonical(document)).unwrap_or_default())
}

/// The document with every object's keys in sorted order (serde_json keeps insertion order).
fn canonical(value: &Value) -> Value {
    match value {
        Value::Object(map) => {
            let mut entries: Vec<(&String, &Value)> = map.iter().collect();
            entries.sort_by(|a, b| a.0.cmp(b.0));
            Value::Object(entries.into_iter().map(|(k, v)| (k.clone(), canonical(v))).collect())
        }
        Value::Array(items) => Value::Array(items.iter().map(canonical).collect()),
        other => other.clone(),
    }
}

fn fnv1a(bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(0xcbf2_9ce4_8422_2325, |hash, &byte| (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_order_and_spacing_do_not_matter() {
        let a: Value =
            serde_json::from_str(r#"{"duration": 1, "bodies": [{"type": "chain", "count": 3}]}"#).unwrap();
        let b: Value =
            serde_json::from_str(r#"{"bodies":[{"count":3,"type":"chain"}],"duration":1}"#).unwrap();
        assert_eq!(fingerprint(&a), fingerprint(&b));
    }

    #[test]
    fn different_documents_differ() {
        let a: Value = serde_json::from_str(r#"{"duration": 1}"#).unwrap();
        let b: Value = serde_json::from_str(r#"{"duration": 2}"#).unwrap();
        assert_ne!(fingerprint(&a), fingerprint(&b));
    }

    #[test]
    fn fnv1a_matches_the_published_test_vectors() {
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(b"foobar"), 0x8594_4171_f739_67e8);
    }
}
