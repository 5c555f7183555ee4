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

/// Fixed-precision number formats for CSV columns (`#[serde(serialize_with = "fmt::e6")]`),
/// so a column keeps the precision its readers expect.
pub mod fmt {
    use serde::Serializer;

    macro_rules! formats {
        ($($(#[$doc:meta])* $name:ident $fmt:literal),*) => {$(
            $(#[$doc])*
            pub fn $name<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
                s.collect_str(&format_args!($fmt, v))
            }
        )*};
    }
    formats!(
        /// Scientific, 6 digits after the point.
        e6 "{:.6e}",
        /// Fixed, 6 decimals.
        f6 "{:.6}",
        /// Fixed, 4 decimals.
        f4 "{:.4}",
        /// Fixed, 2 decimals.
        f2 "{:.2}",
        /// Fixed, 1 decimal.
        f1 "{:.1}"
    );

    /// [`f4`] or an empty field.
    pub fn opt_f4<S: Serializer>(v: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        match v {
            Some(v) => f4(v, s),
            None => s.serialize_none(),
        }
    }

    /// [`f6`] or an empty field.
    pub fn opt_f6<S: Serializer>(v: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        match v {
            Some(v) => f6(v, s),
            None => s.serialize_none(),
        }
    }
}

/// A Markdown table: a header row, its separator, then one line per row.
pub fn markdown_table(header: &[&str], rows: impl IntoIterator<Item = Vec<String>>) -> String {
    let line = |cells: &[String]| format!("| {} |\n", cells.join(" | "));
    let mut md = line(&header.iter().map(|h| h.to_string()).collect::<Vec<_>>());
    md += &line(&vec!["---".to_string(); header.len()]).replace(' ', "");
    rows.into_iter().for_each(|r| md += &line(&r));
    md
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

    #[test]
    fn markdown_table_has_a_separator_row() {
        let md = markdown_table(&["a", "b"], [vec!["1".into(), "2".into()]]);
        assert_eq!(md, "| a | b |\n|---|---|\n| 1 | 2 |\n");
    }
}
