//! A PostgreSQL database of its own for each test, dropped at the end.
//!
//! The server is found at `DRAPE_TEST_POSTGRES` (an admin URL) or at 127.0.0.1:5432 as user
//! `postgres` or `root` (trust auth). The tests that need it are marked `#[ignore]` with that
//! reason, so a plain `cargo test` lists them as ignored; run with `--include-ignored`, they fail
//! when no server answers, naming the addresses tried.

#![allow(dead_code)]

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use sqlx::{Connection, PgConnection};

/// A database made for one test.
pub struct TestDatabase {
    /// Its URL.
    pub url: String,
    admin: String,
    name: String,
}

fn admin_urls() -> Vec<String> {
    match std::env::var("DRAPE_TEST_POSTGRES") {
        Ok(url) => vec![url],
        Err(_) => ["postgres", "root"]
            .iter()
            .map(|user| format!("postgres://{user}@127.0.0.1:5432/postgres"))
            .collect(),
    }
}

impl TestDatabase {
    /// Makes a fresh database; panics, naming the servers tried, if there is none.
    pub async fn create() -> Self {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let nanos = SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_nanos();
        let name = format!(
            "drape_test_{}_{}_{}",
            std::process::id(),
            nanos % 1_000_000_000_000,
            COUNTER.fetch_add(1, Ordering::Relaxed)
        );
        let mut errors = Vec::new();
        for admin in admin_urls() {
            match PgConnection::connect(&admin).await {
                Ok(mut connection) => {
                    sqlx::query(&format!("CREATE DATABASE {name}")).execute(&mut connection).await.unwrap();
                    let _ = connection.close().await;
                    let url = format!("{}/{name}", admin.rsplit_once('/').unwrap().0);
                    return Self { url, admin, name };
                }
                Err(e) => errors.push(format!("{admin}: {e}")),
            }
        }
        panic!(
            "this test needs PostgreSQL (see README.md, Run the tests), and none answered: {}",
            errors.join("; ")
        )
    }
}

impl Drop for TestDatabase {
    fn drop(&mut self) {
        let (admin, name) = (self.admin.clone(), self.name.clone());
        // Drop runs outside any runtime (or inside one that must not block): use a thread of its own.
        let dropped = std::thread::spawn(move || {
            let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
            runtime.block_on(async {
                let mut connection = PgConnection::connect(&admin).await?;
                sqlx::query(&format!("DROP DATABASE IF EXISTS {name} WITH (FORCE)"))
                    .execute(&mut connection)
                    .await?;
                connection.close().await
            })
        })
        .join();
        if !matches!(dropped, Ok(Ok(()))) {
            eprintln!("could not drop the test database {}", self.name);
        }
    }
}
