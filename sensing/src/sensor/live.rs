//! The GelSight's force frame by frame, as frames arrive: a calibrated sensor file read
//! against a tracking pipeline. It is what a run records with `record: {gelsight_force: …}`
//! and what a robot loop calls on each camera frame.
//!
//! The sensor's markers are matched to the pipeline's reference once, at the first frame;
//! the gel's load history (for the relaxation the calibration measured) starts there too.
//! The interior field is read, as calibration and `gelrig track --sensor` read
//! `markers.csv`: border markers' centroids are biased by the image's edge, and counted here
//! they put a live reading 13 % off the same frames read afterwards.

use tracking::Pipeline;
use tracking::field::MarkerField;

use super::SensorFile;
use super::history::{LoadHistory, Region};
use super::reader::{Reader, Wrench};

/// Reads Fx, Fy, Fz and Tz, each with its standard uncertainty, from frame after frame.
pub struct LiveReader {
    reader: Reader,
    /// The sensor's layout matched to the reference markers, from the first frame.
    map: Option<Vec<Option<usize>>>,
    /// The gel's load history, from the first frame.
    history: Option<LoadHistory>,
}

impl LiveReader {
    /// A reader of `sensor` (a file `gelrig calibrate` wrote: [`SensorFile::read`]).
    pub fn new(sensor: &SensorFile) -> Self {
        Self {
            reader: Reader::new(sensor),
            map: None,
            history: None,
        }
    }

    /// The wrench of the frame `pipeline` tracked last, taken at run time `t_ns`; its
    /// contact region, when the pipeline finds one, tells where the load is. An error when
    /// the pipeline's markers are not the sensor's (another gel or camera): the message
    /// names the layouts.
    pub fn read(
        &mut self,
        pipeline: &Pipeline,
        t_ns: u64,
    ) -> Result<Wrench, analysis::force_sensor::SensorError> {
        let field = MarkerField::interior_from_tracker(pipeline.tracker());
        let seen = pipeline.contact().map(|c| Region {
            centroid_px: c.centroid_px,
            radius_px: c.radius_px,
            second_moments_px2: Some(c.second_moments_px2),
        });
        self.read_field(&field, seen, t_ns)
    }

    /// The wrench of one marker `field` with the image's contact region `seen`, if any.
    pub fn read_field(
        &mut self,
        field: &MarkerField,
        seen: Option<Region>,
        t_ns: u64,
    ) -> Result<Wrench, analysis::force_sensor::SensorError> {
        let map = match self.map.take() {
            Some(m) => m,
            None => self.reader.layout.match_markers(&field.reference_px)?,
        };
        let reader = &self.reader;
        // The live path always looks for the contact region.
        let history = self
            .history
            .get_or_insert_with(|| LoadHistory::new(reader.memory(), reader.fz_range_n(), true));
        let region = history.region(field, seen);
        let reading = reader.read(field, region, &map);
        let wrench = reader.wrench(&reading, region, history, t_ns);
        self.map = Some(map);
        Ok(wrench)
    }
}
