//! The results table: one row per point, typed columns, written as Parquet and CSV.
//!
//! A row is kept as a JSON object (`rows/<point>.json`) the moment its point finishes, so an
//! interrupted sweep loses nothing; the tables are rebuilt from the rows in point order, so
//! they are the same whatever the jobs, the order of completion or the sharding.

use std::path::Path;
use std::sync::{Arc, OnceLock};

use parquet::basic::{LogicalType, Repetition, Type as Physical};
use parquet::data_type::{BoolType, ByteArray, ByteArrayType, DoubleType, Int64Type};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;
use serde_json::{Map, Value};
use syncroad_control::record::schema::{metric_infos, MetricInfo};

use crate::output::write_result;

/// A column's type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// 64-bit float.
    Float,
    /// 64-bit integer.
    Int,
    /// Boolean.
    Bool,
    /// UTF-8 text.
    Text,
}

/// A column: its name and type.
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    /// Name.
    pub name: String,
    /// Type.
    pub kind: Kind,
}

impl Column {
    /// A column.
    pub fn new(name: impl Into<String>, kind: Kind) -> Self {
        Self {
            name: name.into(),
            kind,
        }
    }
}

/// Every scalar of `metrics.json` as a dotted path with its column type, from the record's
/// derived schema ([`metric_infos`]), in the record's field order.
pub fn metric_kinds() -> &'static [(String, Kind)] {
    static KINDS: OnceLock<Vec<(String, Kind)>> = OnceLock::new();
    KINDS.get_or_init(|| {
        metric_infos()
            .into_iter()
            .map(|m| {
                let kind = match m.kind {
                    "number" => Kind::Float,
                    "integer" => Kind::Int,
                    "boolean" => Kind::Bool,
                    _ => Kind::Text,
                };
                (m.path, kind)
            })
            .collect()
    })
}

/// `title [unit]` of a metric path, from the record's schema (the path itself when it is no
/// metric of the record).
pub fn metric_label(path: &str) -> String {
    static INFOS: OnceLock<Vec<MetricInfo>> = OnceLock::new();
    INFOS
        .get_or_init(metric_infos)
        .iter()
        .find(|m| m.path == path)
        .map_or_else(|| path.to_string(), MetricInfo::label)
}

/// The value at a dotted path of a JSON document (`Null` when absent).
pub fn at_path<'a>(doc: &'a Value, path: &str) -> &'a Value {
    path.split('.')
        .try_fold(doc, |v, k| v.get(k))
        .unwrap_or(&Value::Null)
}

/// A table: columns and rows (JSON objects keyed by column name).
#[derive(Debug, Clone)]
pub struct Table {
    /// The columns in order.
    pub columns: Vec<Column>,
    /// The rows in order.
    pub rows: Vec<Map<String, Value>>,
}

fn float(v: &Value) -> Option<f64> {
    v.as_f64()
}

fn int(v: &Value) -> Option<i64> {
    v.as_i64()
        .or_else(|| v.as_u64().and_then(|u| i64::try_from(u).ok()))
}

fn text(v: &Value) -> Option<String> {
    match v {
        Value::Null => None,
        Value::String(s) => Some(s.clone()),
        other => Some(other.to_string()),
    }
}

impl Table {
    /// The Parquet schema of the table: one optional (nullable) column per column, floats as
    /// DOUBLE, integers as INT64, booleans as BOOLEAN, text as UTF-8 strings.
    fn parquet_schema(&self) -> anyhow::Result<Arc<Type>> {
        let fields = self
            .columns
            .iter()
            .map(|c| {
                let (physical, logical) = match c.kind {
                    Kind::Float => (Physical::DOUBLE, None),
                    Kind::Int => (Physical::INT64, None),
                    Kind::Bool => (Physical::BOOLEAN, None),
                    Kind::Text => (Physical::BYTE_ARRAY, Some(LogicalType::String)),
                };
                Ok(Arc::new(
                    Type::primitive_type_builder(&c.name, physical)
                        .with_repetition(Repetition::OPTIONAL)
                        .with_logical_type(logical)
                        .build()?,
                ))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        Ok(Arc::new(
            Type::group_type_builder("schema")
                .with_fields(fields)
                .build()?,
        ))
    }

    /// Writes the table as Parquet, one row group (a result file, replaced atomically); a
    /// missing value is a null.
    pub fn write_parquet(&self, path: &Path) -> anyhow::Result<()> {
        let schema = self.parquet_schema()?;
        Ok(write_result(path, |f| -> anyhow::Result<()> {
            let props = Arc::new(WriterProperties::builder().build());
            let mut w = SerializedFileWriter::new(f, schema.clone(), props)?;
            let mut group = w.next_row_group()?;
            for c in &self.columns {
                let cells: Vec<Value> = self
                    .rows
                    .iter()
                    .map(|r| r.get(&c.name).cloned().unwrap_or_default())
                    .collect();
                let mut col = group
                    .next_column()?
                    .ok_or_else(|| anyhow::anyhow!("Parquet writer: no column for {}", c.name))?;
                // Definition level 1: the value is present; 0: null.
                fn levels<T>(cells: &[Option<T>]) -> Vec<i16> {
                    cells.iter().map(|c| i16::from(c.is_some())).collect()
                }
                match c.kind {
                    Kind::Float => {
                        let v: Vec<Option<f64>> = cells.iter().map(float).collect();
                        let present: Vec<f64> = v.iter().flatten().copied().collect();
                        col.typed::<DoubleType>()
                            .write_batch(&present, Some(&levels(&v)), None)?;
                    }
                    Kind::Int => {
                        let v: Vec<Option<i64>> = cells.iter().map(int).collect();
                        let present: Vec<i64> = v.iter().flatten().copied().collect();
                        col.typed::<Int64Type>()
                            .write_batch(&present, Some(&levels(&v)), None)?;
                    }
                    Kind::Bool => {
                        let v: Vec<Option<bool>> = cells.iter().map(Value::as_bool).collect();
                        let present: Vec<bool> = v.iter().flatten().copied().collect();
                        col.typed::<BoolType>()
                            .write_batch(&present, Some(&levels(&v)), None)?;
                    }
                    Kind::Text => {
                        let v: Vec<Option<String>> = cells.iter().map(text).collect();
                        let present: Vec<ByteArray> = v
                            .iter()
                            .flatten()
                            .map(|s| ByteArray::from(s.as_str()))
                            .collect();
                        col.typed::<ByteArrayType>().write_batch(
                            &present,
                            Some(&levels(&v)),
                            None,
                        )?;
                    }
                }
                col.close()?;
            }
            group.close()?;
            w.close()?;
            Ok(())
        })?)
    }

    /// Writes the table as CSV (empty cells for missing values; a result file, replaced
    /// atomically).
    pub fn write_csv(&self, path: &Path) -> anyhow::Result<()> {
        Ok(write_result(path, |f| self.write_csv_to(f))?)
    }

    fn write_csv_to(&self, f: &mut (dyn std::io::Write + Send)) -> anyhow::Result<()> {
        let mut w = csv::Writer::from_writer(f);
        w.write_record(self.columns.iter().map(|c| c.name.as_str()))?;
        for r in &self.rows {
            w.write_record(self.columns.iter().map(|c| {
                let v = r.get(&c.name).cloned().unwrap_or_default();
                match c.kind {
                    Kind::Float => float(&v).map_or(String::new(), |x| x.to_string()),
                    Kind::Int => int(&v).map_or(String::new(), |x| x.to_string()),
                    Kind::Bool => v.as_bool().map_or(String::new(), |b| b.to_string()),
                    Kind::Text => text(&v).unwrap_or_default(),
                }
            }))?;
        }
        w.flush()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_schema_gives_typed_metric_paths() {
        let k = metric_kinds();
        let find = |p: &str| k.iter().find(|(q, _)| q == p).map(|(_, t)| *t);
        assert_eq!(find("sync.verdict"), Some(Kind::Text));
        assert_eq!(find("sync.final_spread_mps"), Some(Kind::Float));
        assert_eq!(find("safety.collision_steps"), Some(Kind::Int));
        assert_eq!(find("certified"), Some(Kind::Bool));
        assert_eq!(find("sync.thresholds.tolerance_mps"), Some(Kind::Float));
        assert_eq!(find("stop.reason"), Some(Kind::Text));
        assert_eq!(metric_label("congestion.speed_std_mps"), "speed std [m/s]");
        // The gap certificate's numbers are sweep columns too.
        assert_eq!(
            find("gap_certificate.worst_shrinkage_m_per_mps"),
            Some(Kind::Float)
        );
        assert_eq!(find("gap_certificate.contact_predicted"), Some(Kind::Bool));
        // Arrays are not scalar metrics.
        assert_eq!(find("drivers"), None);
    }

    #[test]
    fn cells_keep_their_types_and_gaps() {
        let t = Table {
            columns: vec![
                Column::new("x", Kind::Float),
                Column::new("n", Kind::Int),
                Column::new("ok", Kind::Bool),
                Column::new("s", Kind::Text),
            ],
            rows: vec![
                serde_json::from_str(r#"{"x": 0.1, "n": 3, "ok": true, "s": "a,b"}"#).unwrap(),
                serde_json::from_str(r#"{"x": null, "n": 2}"#).unwrap(),
            ],
        };
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        t.write_csv(&dir.join("t.csv")).unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.join("t.csv")).unwrap(),
            "x,n,ok,s\n0.1,3,true,\"a,b\"\n,2,,\n"
        );
        t.write_parquet(&dir.join("t.parquet")).unwrap();
        let bytes = std::fs::read(dir.join("t.parquet")).unwrap();
        assert_eq!(&bytes[..4], b"PAR1");
        // Read back row by row: values where given, nulls where missing (pandas reads the
        // same file in the Python tests and the demo).
        use parquet::file::reader::{FileReader, SerializedFileReader};
        use parquet::record::{Field, RowAccessor};
        let r =
            SerializedFileReader::new(std::fs::File::open(dir.join("t.parquet")).unwrap()).unwrap();
        let rows: Vec<_> = r.get_row_iter(None).unwrap().map(|x| x.unwrap()).collect();
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[0].get_double(0).unwrap(), 0.1);
        assert_eq!(rows[0].get_long(1).unwrap(), 3);
        assert!(rows[0].get_bool(2).unwrap());
        assert_eq!(rows[0].get_string(3).unwrap(), "a,b");
        let nulls: Vec<bool> = rows[1]
            .get_column_iter()
            .map(|(_, f)| matches!(f, Field::Null))
            .collect();
        assert_eq!(nulls, [true, false, true, true]);
        assert_eq!(rows[1].get_long(1).unwrap(), 2);
    }
}
