//! A shard's rows as Arrow columns, with the Hugging Face `datasets` features of each column
//! in the schema's `huggingface` metadata (so the images decode as images).

use std::collections::HashMap;
use std::sync::Arc;

use arrow_array::builder::{BinaryBuilder, Float32Builder, ListBuilder, StringBuilder};
use arrow_array::{
    Array, ArrayRef, Float64Array, Int64Array, RecordBatch, StringArray, StructArray,
};
use arrow_schema::{DataType, Field, Fields, Schema};

use super::{FLOATS, INTS, MARKERS, Row, TEXTS};

/// Columns being built: their fields, arrays and `datasets` features.
#[derive(Default)]
struct Columns {
    fields: Vec<Field>,
    arrays: Vec<ArrayRef>,
    features: serde_json::Map<String, serde_json::Value>,
}

fn value(dtype: &str) -> serde_json::Value {
    serde_json::json!({"dtype": dtype, "_type": "Value"})
}

impl Columns {
    fn push(&mut self, name: &str, array: ArrayRef, feature: serde_json::Value) {
        self.fields
            .push(Field::new(name, array.data_type().clone(), true));
        self.arrays.push(array);
        self.features.insert(name.into(), feature);
    }

    /// An image column as the `Image` feature stores one: {bytes, path}; `None`: null.
    fn image(&mut self, name: &str, images: &[Option<(&[u8], &str)>]) {
        let mut bytes = BinaryBuilder::new();
        let mut paths = StringBuilder::new();
        let mut valid = Vec::with_capacity(images.len());
        for im in images {
            match im {
                Some((b, p)) => {
                    bytes.append_value(b);
                    paths.append_value(p);
                }
                None => {
                    bytes.append_null();
                    paths.append_null();
                }
            }
            valid.push(im.is_some());
        }
        let fields = Fields::from(vec![
            Field::new("bytes", DataType::Binary, true),
            Field::new("path", DataType::Utf8, true),
        ]);
        let array = StructArray::new(
            fields,
            vec![
                Arc::new(bytes.finish()) as ArrayRef,
                Arc::new(paths.finish()),
            ],
            Some(valid.into()),
        );
        self.push(name, Arc::new(array), serde_json::json!({"_type": "Image"}));
    }

    fn text(&mut self, name: &str, values: Vec<&str>) {
        self.push(name, Arc::new(StringArray::from(values)), value("string"));
    }

    fn floats(&mut self, name: &str, values: Vec<Option<f64>>) {
        self.push(name, Arc::new(Float64Array::from(values)), value("float64"));
    }
}

/// The rows as one record batch, with the `huggingface` features in the schema's metadata.
pub(super) fn batch(rows: &[Row], params: &[String]) -> Result<RecordBatch, String> {
    let mut c = Columns::default();
    let frames: Vec<Option<(&[u8], &str)>> = rows
        .iter()
        .map(|r| Some((r.png.as_slice(), r.file.as_str())))
        .collect();
    c.image("image", &frames);
    c.text("run", rows.iter().map(|r| r.run.as_str()).collect());
    for (k, p) in params.iter().enumerate() {
        let vals: Vec<&str> = rows.iter().map(|r| r.params[k].as_str()).collect();
        if vals.iter().all(|v| v.parse::<f64>().is_ok()) {
            c.floats(p, vals.iter().map(|v| v.parse::<f64>().ok()).collect());
        } else {
            c.text(p, vals);
        }
    }
    for (k, name) in INTS.iter().enumerate() {
        let ints = Int64Array::from(rows.iter().map(|r| r.ints[k]).collect::<Vec<_>>());
        c.push(name, Arc::new(ints), value("int64"));
    }
    for (k, name) in FLOATS.iter().enumerate() {
        c.floats(name, rows.iter().map(|r| r.floats[k]).collect());
    }
    for (k, name) in TEXTS.iter().enumerate() {
        c.text(name, rows.iter().map(|r| r.texts[k].as_str()).collect());
    }
    for (k, name) in MARKERS.iter().enumerate() {
        let mut list = ListBuilder::new(Float32Builder::new());
        for r in rows {
            list.values().append_slice(&r.markers[k]);
            list.append(true);
        }
        let feature = serde_json::json!({"feature": value("float32"), "_type": "Sequence"});
        c.push(name, Arc::new(list.finish()), feature);
    }
    // The simulator's maps (null for a frame without them), row-major H×W.
    type Channel = fn(&super::maps::FrameMaps) -> &Vec<f32>;
    let channels: [(&str, Channel); 3] = [
        ("pressure_kpa", |m| &m.pressure_kpa),
        ("shear_x_kpa", |m| &m.shear_x_kpa),
        ("shear_y_kpa", |m| &m.shear_y_kpa),
    ];
    for (name, channel) in channels {
        let mut list = ListBuilder::new(Float32Builder::new());
        for r in rows {
            match &r.maps {
                Some(m) => {
                    list.values().append_slice(channel(m));
                    list.append(true);
                }
                None => list.append(false),
            }
        }
        let feature = serde_json::json!({"feature": value("float32"), "_type": "Sequence"});
        c.push(name, Arc::new(list.finish()), feature);
    }
    let masks: Vec<Option<(&[u8], &str)>> = rows
        .iter()
        .map(|r| r.maps.as_ref().map(|m| (m.mask_png.as_slice(), "")))
        .collect();
    c.image("contact_mask", &masks);
    let meta = serde_json::json!({"info": {"features": c.features}}).to_string();
    let schema =
        Schema::new(c.fields).with_metadata(HashMap::from([("huggingface".to_string(), meta)]));
    RecordBatch::try_new(Arc::new(schema), c.arrays).map_err(|e| e.to_string())
}
