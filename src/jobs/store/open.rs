//! Choosing a job store: `memory`, `sqlite://PATH` or `postgres://...`, and opening it.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;
use std::sync::Arc;

use super::{JobStore, MemoryStore, PostgresStore, SqliteStore, StoreError};

/// Where jobs are kept, as given to `--store`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StoreUrl {
    /// In this process's memory; lost when it ends.
    Memory,
    /// A SQLite file, created if missing.
    Sqlite(PathBuf),
    /// A PostgreSQL database, shared by every instance given the same URL.
    Postgres(String),
}

impl FromStr for StoreUrl {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        if text == "memory" {
            Ok(Self::Memory)
        } else if let Some(path) = text.strip_prefix("sqlite://") {
            if path.is_empty() {
                return Err("`sqlite://` needs a file path, e.g. `sqlite://drape.db`".into());
            }
            Ok(Self::Sqlite(PathBuf::from(path)))
        } else if text.starts_with("postgres://") || text.starts_with("postgresql://") {
            Ok(Self::Postgres(text.to_string()))
        } else {
            Err(format!("`{text}` is not `memory`, `sqlite://PATH` or `postgres://...`"))
        }
    }
}

impl fmt::Display for StoreUrl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Memory => f.write_str("memory"),
            Self::Sqlite(path) => write!(f, "sqlite://{}", path.display()),
            // The URL may hold a password; show only where it points.
            Self::Postgres(url) => {
                let host = url.rsplit('@').next().unwrap_or(url).trim_start_matches("postgres://");
                write!(f, "postgres://…@{}", host.trim_start_matches("postgresql://"))
            }
        }
    }
}

impl StoreUrl {
    /// Opens the store, creating and migrating its schema as needed. `connections` bounds a
    /// PostgreSQL pool; the memory store keeps the `retain` most recent ended jobs.
    pub async fn open(&self, connections: u32, retain: usize) -> Result<Arc<dyn JobStore>, StoreError> {
        Ok(match self {
            Self::Memory => Arc::new(MemoryStore::retaining(retain)),
            Self::Sqlite(path) => Arc::new(SqliteStore::open(path).await?),
            Self::Postgres(url) => Arc::new(PostgresStore::open(url, connections).await?),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_parse() {
        assert_eq!("memory".parse(), Ok(StoreUrl::Memory));
        assert_eq!("sqlite://drape.db".parse(), Ok(StoreUrl::Sqlite("drape.db".into())));
        assert_eq!("sqlite:///var/lib/drape.db".parse(), Ok(StoreUrl::Sqlite("/var/lib/drape.db".into())));
        assert_eq!(
            "postgres://drape@db:5432/drape".parse(),
            Ok(StoreUrl::Postgres("postgres://drape@db:5432/drape".into()))
        );
        for bad in ["", "sqlite://", "mysql://x", "drape.db"] {
            assert!(bad.parse::<StoreUrl>().is_err(), "{bad:?}");
        }
    }

    #[test]
    fn a_postgres_password_is_not_shown() {
        let url: StoreUrl = "postgres://drape:secret@db:5432/drape".parse().unwrap();
        assert_eq!(url.to_string(), "postgres://…@db:5432/drape");
    }
}
