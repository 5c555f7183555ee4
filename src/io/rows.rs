//! CSV tables of serde rows: one struct per row type, the header from its
//! field names, so no column is formatted or parsed by hand.

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::path::Path;

/// Writes `rows` to `path` as CSV with a header row.
pub fn write_rows<T: Serialize>(path: &Path, rows: &[T]) -> Result<()> {
    let fail = |e: &dyn std::fmt::Display| Error(format!("cannot write {}: {e}", path.display()));
    let mut w = csv::Writer::from_path(path).map_err(|e| fail(&e))?;
    for r in rows {
        w.serialize(r).map_err(|e| fail(&e))?;
    }
    w.flush().map_err(|e| fail(&e))
}

/// Reads every row of the CSV file at `path`.
pub fn read_rows<T: DeserializeOwned>(path: &Path) -> Result<Vec<T>> {
    let fail = |e: &dyn std::fmt::Display| Error(format!("{}: {e}", path.display()));
    let mut r = csv::Reader::from_path(path).map_err(|e| fail(&e))?;
    r.deserialize().map(|row| row.map_err(|e| fail(&e))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Serialize, Deserialize, PartialEq, Debug)]
    struct Row {
        name: String,
        value: f64,
    }

    #[test]
    fn rows_round_trip() {
        let path = std::env::temp_dir().join(format!("dualphoton-rows-{}.csv", std::process::id()));
        let rows = vec![Row { name: "a".into(), value: 0.1 }, Row { name: "b".into(), value: f64::NAN }];
        write_rows(&path, &rows).unwrap();
        let back: Vec<Row> = read_rows(&path).unwrap();
        assert_eq!(back[0], rows[0]);
        assert!(back[1].value.is_nan());
        let _ = std::fs::remove_file(path);
    }
}
