//! The emulated sensors: per-unit constants drawn from the seed and the gyro, accelerometer
//! and data reports synthesised from the ground-truth motion with the error model of
//! `PROTOCOL.md` §13.3.

use glam::DMat3;

use super::reports::MpPhase;
use super::{EmulatedRemote, SensorModel};
use crate::controllers::motion::{self, Motion};
use crate::controllers::rng::Rng;
use crate::controllers::wiimote::ir::{IR_MODE_REGISTER, IrCamera, encode_basic, encode_extended};
use crate::controllers::wiimote::protocol::{
    self, AccelCalibration, AccelRaw, GyroRange, MotionPlusCalibration, MotionPlusFrame,
    encode_buttons_accel,
};

/// Per-unit sensor constants drawn from the seed.
#[derive(Debug, Clone)]
pub(super) struct Unit {
    pub(super) gyro_rest: [f64; 3],
    pub(super) gyro_k_slow: [f64; 3],
    pub(super) gyro_k_fast: [f64; 3],
    pub(super) gyro_bias: [f64; 3],
    pub(super) gyro_temp: [f64; 3],
    pub(super) gyro_mis: DMat3,
    pub(super) accel_cal: AccelCalibration,
    pub(super) accel_true_zero: [f64; 3],
    pub(super) accel_true_span: [f64; 3],
    pub(super) accel_mis: DMat3,
    pub(super) mp_cal: MotionPlusCalibration,
}

impl Unit {
    pub(super) fn draw(rng: &mut Rng, s: &SensorModel) -> Self {
        let k_slow = s.gyro_slow_counts_per_dps.unwrap_or_else(|| {
            [
                rng.range(14.2, 20.1),
                rng.range(14.2, 20.1),
                rng.range(14.2, 20.1),
            ]
        });
        let pol = if s.reversed { -1.0 } else { 1.0 };
        let gyro_k_slow = k_slow.map(|k| k * pol);
        let mut gyro_k_fast = [0.0; 3];
        for a in 0..3 {
            gyro_k_fast[a] = gyro_k_slow[a] / rng.range(3.6, 4.4);
        }
        let gyro_rest = [0; 3].map(|_: i32| rng.range(7100.0, 8100.0));
        let gyro_bias = [0; 3].map(|_: i32| rng.normal() * s.gyro_turn_on_bias_dps);
        let gyro_temp = [0; 3].map(|_: i32| {
            s.gyro_temperature_drift_dps
                * if rng.uniform() < 0.5 { -1.0 } else { 1.0 }
                * rng.range(0.3, 1.0)
        });
        let mis = |rng: &mut Rng, cross: f64, scale: f64| {
            let mut m = DMat3::IDENTITY;
            for c in 0..3 {
                for r in 0..3 {
                    let e = if r == c { scale } else { cross };
                    let v = m.col(c)[r] + rng.range(-e, e);
                    m.col_mut(c)[r] = v;
                }
            }
            m
        };
        // Gyro scale errors live in the calibration block; only cross-axis terms here.
        let gyro_mis = mis(rng, s.gyro_misalignment, 0.0);
        let accel_true_zero = [0; 3].map(|_: i32| 512.0 + rng.normal() * 6.0);
        let accel_true_span = [0; 3].map(|_: i32| rng.range(100.0, 111.0));
        let accel_cal = AccelCalibration {
            zero: std::array::from_fn(|a| {
                (accel_true_zero[a] + rng.range(-1.0, 1.0)).round() as u16
            }),
            one_g: std::array::from_fn(|a| {
                (accel_true_zero[a] + accel_true_span[a] + rng.range(-1.0, 1.0)).round() as u16
            }),
        };
        let accel_mis = mis(rng, s.accel_misalignment, s.accel_scale_error);
        // Calibration block: scale − zero = 4·k·degrees·sign (sign yaw −1, roll +1, pitch −1).
        let sign = [-1.0, 1.0, -1.0];
        let range = |k: [f64; 3], degrees: u16, uid: u8, rng: &mut Rng| {
            let mut zero = [0u16; 3];
            let mut scale = [0u16; 3];
            for a in 0..3 {
                let z = 4.0 * gyro_rest[a] + rng.normal() * s.gyro_block_zero_error;
                let err = 1.0 + rng.range(-s.gyro_block_scale_error, s.gyro_block_scale_error);
                let sc = z + 4.0 * k[a] * err * degrees as f64 * sign[a];
                zero[a] = z.round().clamp(0.0, 65535.0) as u16;
                scale[a] = sc.round().clamp(0.0, 65535.0) as u16;
            }
            GyroRange {
                zero,
                scale,
                degrees,
                uid,
            }
        };
        let fast = range(gyro_k_fast, 1200, 0x4F, rng);
        let slow = range(gyro_k_slow, 270, 0xE5, rng);
        Self {
            gyro_rest,
            gyro_k_slow,
            gyro_k_fast,
            gyro_bias,
            gyro_temp,
            gyro_mis,
            accel_cal,
            accel_true_zero,
            accel_true_span,
            accel_mis,
            mp_cal: MotionPlusCalibration { fast, slow },
        }
    }
}

impl EmulatedRemote {
    pub(super) fn bias_dps(&self, t: f64) -> [f64; 3] {
        let ramp = (t / 600.0).min(1.0);
        std::array::from_fn(|a| {
            self.unit.gyro_bias[a] + self.bias_walk[a] + self.unit.gyro_temp[a] * ramp
        })
    }

    pub(super) fn gyro_frame(
        &mut self,
        t: f64,
        motion: &dyn Motion,
        ext_connected: bool,
    ) -> MotionPlusFrame {
        let s = &self.config.sensors;
        let dt = (t - self.last_sensor_t).max(0.0);
        self.last_sensor_t = t;
        for b in &mut self.bias_walk {
            *b += self.rng.normal() * s.gyro_bias_walk * dt.sqrt();
        }
        let w =
            self.unit.gyro_mis * (motion::body_rate(motion, t) * (180.0 / std::f64::consts::PI));
        let bias = self.bias_dps(t);
        // Frame axis order: yaw (z), roll (y), pitch (x).
        let rates = [w.z, w.y, w.x];
        let noise_scale = (self.config.report_rate_hz / 100.0).sqrt();
        let mut raw = [0u16; 3];
        for a in 0..3 {
            let rate = rates[a] + bias[a] + self.rng.normal() * s.gyro_noise_dps * noise_scale;
            let slow_limit = 8191.0 / self.unit.gyro_k_slow[a].abs();
            let threshold = slow_limit.min(440.0);
            if self.gyro_slow[a] && rate.abs() > threshold {
                self.gyro_slow[a] = false;
            } else if !self.gyro_slow[a] && rate.abs() < threshold * 0.9 {
                self.gyro_slow[a] = true;
            }
            let k = if self.gyro_slow[a] {
                self.unit.gyro_k_slow[a]
            } else {
                self.unit.gyro_k_fast[a]
            };
            let counts = (self.unit.gyro_rest[a] + k * rate).round();
            raw[a] = counts.clamp(0.0, 16383.0) as u16;
        }
        MotionPlusFrame {
            yaw: raw[0],
            roll: raw[1],
            pitch: raw[2],
            slow: self.gyro_slow,
            extension_connected: ext_connected,
        }
    }

    pub(super) fn accel(&mut self, t: f64, motion: &dyn Motion) -> AccelRaw {
        let s = &self.config.sensors;
        let f = self.unit.accel_mis * motion::specific_force_g(motion, t);
        let mut raw = [0u16; 3];
        for a in 0..3 {
            let g = (f[a] + self.rng.normal() * s.accel_noise_g).clamp(-3.6, 3.6);
            let counts = (self.unit.accel_true_zero[a] + self.unit.accel_true_span[a] * g).round();
            let mut c = counts.clamp(0.0, 1023.0) as u16;
            if a > 0 {
                c &= !1;
            }
            raw[a] = c;
        }
        AccelRaw(raw)
    }

    pub(super) fn data_report(&mut self, sample_t: f64) -> Vec<u8> {
        let motion = self.controls.motion();
        let buttons = self.buttons();
        let accel = self.accel(sample_t, &*motion);
        let nunchuk = self.controls.with(|s| s.nunchuk);
        let ext: [u8; 6] = match self.mp {
            MpPhase::Active { mode } => {
                self.frame_counter += 1;
                let passthrough =
                    mode != 0x04 && nunchuk.is_some() && self.frame_counter.is_multiple_of(2);
                let gyro = self.gyro_frame(sample_t, &*motion, nunchuk.is_some());
                if self.garbage_left > 0 {
                    self.garbage_left -= 1;
                    let mut g = [0u8; 6];
                    for b in &mut g {
                        *b = self.rng.next_u64() as u8;
                    }
                    g[5] = (g[5] | 0x02) & !0x01;
                    g
                } else if passthrough {
                    nunchuk
                        .map(|n| protocol::nunchuk_passthrough_bytes(&n, true))
                        .unwrap_or([0; 6])
                } else {
                    gyro.encode()
                }
            }
            _ => match nunchuk {
                Some(n) if self.ext_initialized => protocol::nunchuk_direct_bytes(&n),
                _ => [0xFF; 6],
            },
        };
        let ba = encode_buttons_accel(buttons, accel);
        let bb = buttons.to_bytes();
        let (basic, extended) = self.ir_bytes(sample_t, &*motion);
        let mut r = vec![self.mode];
        match self.mode {
            0x30 => r.extend_from_slice(&bb),
            0x31 => r.extend_from_slice(&ba),
            0x32 => {
                r.extend_from_slice(&bb);
                r.extend_from_slice(&ext);
                r.extend_from_slice(&[0; 2]);
            }
            0x33 => {
                r.extend_from_slice(&ba);
                r.extend_from_slice(&extended);
            }
            0x34 => {
                r.extend_from_slice(&bb);
                r.extend_from_slice(&ext);
                r.extend_from_slice(&[0; 13]);
            }
            0x35 => {
                r.extend_from_slice(&ba);
                r.extend_from_slice(&ext);
                r.extend_from_slice(&[0; 10]);
            }
            0x36 => {
                r.extend_from_slice(&bb);
                r.extend_from_slice(&basic);
                r.extend_from_slice(&ext);
                r.extend_from_slice(&[0; 3]);
            }
            0x37 => {
                r.extend_from_slice(&ba);
                r.extend_from_slice(&basic);
                r.extend_from_slice(&ext);
            }
            _ => {
                r.extend_from_slice(&ext);
                r.extend_from_slice(&[0; 15]);
            }
        }
        r
    }

    /// The camera's bytes for this sample, basic (10) and extended (12): the sensor bar's
    /// clusters projected from the emulated pose, when the camera is on (its mode register
    /// set by the host) and sees a bar; empty slots (0xFF) otherwise.
    fn ir_bytes(&mut self, sample_t: f64, motion: &dyn Motion) -> ([u8; 10], [u8; 12]) {
        let mode = self.camera_regs[(IR_MODE_REGISTER & 0xFF) as usize];
        let on = self.config.camera && matches!(mode, 1 | 3 | 5);
        let Some(bar) = self.config.sensor_bar.filter(|_| on) else {
            return ([0xFF; 10], [0xFF; 12]);
        };
        let orientation = motion.orientation(sample_t);
        let rng = &mut self.rng;
        let dots = IrCamera::default().project_with_noise(
            &bar.setup,
            bar.position,
            orientation,
            &mut |_| rng.normal() * bar.noise_px,
        );
        (encode_basic(&dots), encode_extended(&dots))
    }
}
