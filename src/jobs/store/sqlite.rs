//! The SQLite job store: one file, the default, for a single drape instance.
//!
//! Jobs and results survive a restart. The file is created on first open and migrated to the
//! schema in `migrations/sqlite`. Only one instance may use a file: on open, every job left
//! `running` belonged to a process that is gone, so its lease is lapsed at once and the job runs
//! again from the start; so does every sweep run left `running`.

use std::path::Path;
use std::str::FromStr;
use std::time::Duration;

use sqlx::SqlitePool;
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};

use super::StoreError;
use super::sql::{Dialect, Statements, backend, sql_store};

/// Jobs in a SQLite file.
pub struct SqliteStore {
    pool: SqlitePool,
    sql: Statements,
}

impl SqliteStore {
    /// Opens (creating if needed) and migrates the database at `path`.
    pub async fn open(path: &Path) -> Result<Self, StoreError> {
        let options = SqliteConnectOptions::from_str("sqlite:")
            .map_err(backend)?
            .filename(path)
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Normal)
            .busy_timeout(Duration::from_secs(10))
            .foreign_keys(true);
        let pool = SqlitePoolOptions::new().max_connections(4).connect_with(options).await.map_err(|e| {
            StoreError::Backend(format!("cannot open the SQLite store {}: {e}", path.display()))
        })?;
        sqlx::migrate!("migrations/sqlite")
            .run(&pool)
            .await
            .map_err(|e| StoreError::Backend(format!("cannot migrate the SQLite store: {e}")))?;
        for table in ["jobs", "sweep_runs"] {
            sqlx::query(&format!("UPDATE {table} SET lease_until_ms = 0 WHERE status = 'running'"))
                .execute(&pool)
                .await
                .map_err(backend)?;
        }
        Ok(Self { pool, sql: Statements::new(Dialect::Sqlite) })
    }
}

sql_store!(SqliteStore);
