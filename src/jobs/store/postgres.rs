//! The PostgreSQL job store: one queue shared by several drape instances.
//!
//! Each instance's workers claim jobs with `SELECT ... FOR UPDATE SKIP LOCKED` and hold them
//! under a lease that the instance renews while the job runs; a job whose instance died is
//! claimed again once its lease lapses. The schema is `migrations/postgres`, applied on open
//! (sqlx takes an advisory lock, so instances starting together migrate once).

use std::time::Duration;

use sqlx::PgPool;
use sqlx::postgres::PgPoolOptions;

use super::StoreError;
use super::sql::{Dialect, Statements, sql_store};

/// Jobs in a PostgreSQL database.
pub struct PostgresStore {
    pool: PgPool,
    sql: Statements,
}

impl PostgresStore {
    /// Connects to `url` (`postgres://...`) and migrates the database.
    pub async fn open(url: &str, max_connections: u32) -> Result<Self, StoreError> {
        let pool = PgPoolOptions::new()
            .max_connections(max_connections)
            .acquire_timeout(Duration::from_secs(10))
            .connect(url)
            .await
            .map_err(|e| StoreError::Backend(format!("cannot connect to PostgreSQL: {e}")))?;
        sqlx::migrate!("migrations/postgres")
            .run(&pool)
            .await
            .map_err(|e| StoreError::Backend(format!("cannot migrate the PostgreSQL store: {e}")))?;
        Ok(Self { pool, sql: Statements::new(Dialect::Postgres) })
    }
}

sql_store!(PostgresStore);
