//! Loading the scenario's debris scene and sensor model.

use crate::{ConfigError, Scenario};
use dkrrt_debris::{Scene, SensorConfig};

impl Scenario {
    /// The debris scene of `debris.scene` (a named scene or a scene file); the error names
    /// the field.
    pub fn load_debris_scene(&self) -> Result<Scene, ConfigError> {
        if let Some(s) = &self.scene_override {
            return Ok(s.clone());
        }
        let r = match self.debris_scene_path() {
            Some(p) => Scene::from_file(&p),
            None => Scene::named(&self.debris.scene),
        };
        r.map_err(|e| ConfigError::Invalid {
            origin: self.origin_name(),
            field: "debris.scene".into(),
            value: format!("{:?}", self.debris.scene),
            reason: e.to_string(),
        })
    }

    /// The debris sensor model of the `[debris]` table.
    pub fn sensor_config(&self) -> SensorConfig {
        let d = &self.debris;
        SensorConfig {
            rate_hz: d.sensor_rate_hz,
            pos_sigma: d.pos_sigma_m,
            att_sigma: d.att_sigma_rad,
            report_rates: d.report_rates,
            vel_sigma: d.vel_sigma_mps,
            rate_sigma: d.rate_sigma_radps,
            dropout_prob: d.dropout,
            latency: d.latency_s,
            latency_jitter: d.latency_jitter_s,
            ..SensorConfig::default()
        }
    }
}
