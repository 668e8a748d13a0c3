//! The `Idempotency-Key` a client request carries.
//!
//! The key is `drape-` and the SHA-256, in hex, of the request target
//! (`POST /jobs?format=npy`), a line break, the body as sent (the scene with its mesh files in
//! place), and, if given, a line break and the `--idempotency-key` value. A step that is retried
//! sends the same request, so the server answers it with the job it already has instead of
//! queueing another; changing the scene, the format or the value runs it anew.

use sha2::{Digest, Sha256};

/// The key of a request to `target` with `body`, mixed with the caller's `salt` if any.
pub fn idempotency_key(target: &str, body: &[u8], salt: Option<&str>) -> String {
    let mut hash = Sha256::new();
    hash.update(target.as_bytes());
    hash.update(b"\n");
    hash.update(body);
    if let Some(salt) = salt {
        hash.update(b"\n");
        hash.update(salt.as_bytes());
    }
    let digest = hash.finalize();
    let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
    format!("drape-{hex}")
}

#[cfg(test)]
mod tests {
    use super::idempotency_key;

    #[test]
    fn the_key_is_the_hash_of_target_body_and_salt() {
        // SHA-256 of "POST /jobs\n{}" and of "POST /jobs\n{}\nci-1", from `sha256sum`.
        assert_eq!(
            idempotency_key("POST /jobs", b"{}", None),
            "drape-764dd267eb8618f600903c97cfa79b0f460b630543fd12e3cd39dbd428739fff"
        );
        assert_eq!(
            idempotency_key("POST /jobs", b"{}", Some("ci-1")),
            "drape-814d5f1018298a52e193c5c63beb153fc1745e919a11ade837af96f6df39294a"
        );
    }
}
