//! Streaming: polling reports, status and extension changes, buttons, and the IMU samples
//! fed to the orientation filter (`PROTOCOL.md` §5, §11).

use super::*;

impl<T: Transport> Session<T> {
    /// Reads and handles at most one report (waiting up to `timeout_ms`), then runs the
    /// periodic duties: battery status every 10 s, MotionPlus watchdog and re-probe.
    pub fn poll(&mut self, timeout_ms: u32) -> Result<(), SessionError> {
        self.pump(timeout_ms)?;
        if !self.connected {
            return Ok(());
        }
        let now = self.now();
        if now.saturating_sub(self.last_battery_us) >= self.config.battery_interval_ms as u64 * 1000
        {
            self.last_battery_us = now;
            self.write(OutputReport::StatusRequest {
                rumble: self.rumble,
            })?;
        }
        let watchdog = self.config.motion_plus_timeout_ms as u64 * 1000;
        let needs_probe = match self.mp_state {
            MotionPlusState::Active => now.saturating_sub(self.last_mp_frame_us) > watchdog,
            MotionPlusState::Lost | MotionPlusState::Absent => {
                self.kind == RemoteKind::Original && now >= self.next_mp_probe_us
            }
            MotionPlusState::Activating => false,
        };
        if needs_probe {
            if self.mp_state == MotionPlusState::Active {
                self.set_mp_state(MotionPlusState::Lost);
            }
            self.next_mp_probe_us = now + self.config.motion_plus_poll_ms as u64 * 1000;
            match self.probe_motion_plus() {
                Ok(_) => {}
                Err(e @ SessionError::Transport(_)) => return Err(e),
                Err(_) => {}
            }
            self.mode = self.streaming_mode();
            self.command(self.mode_report())?;
        }
        Ok(())
    }

    /// Reads one report and dispatches it.
    pub(super) fn pump(&mut self, timeout_ms: u32) -> Result<(), SessionError> {
        let mut buf = [0u8; 32];
        let n = self.transport.read_timeout(&mut buf, timeout_ms)?;
        if n == 0 {
            return Ok(());
        }
        let report = match InputReport::decode(&buf[..n]) {
            Ok(r) => r,
            Err(_) => {
                self.malformed += 1;
                return Ok(());
            }
        };
        let now = self.now();
        match report {
            InputReport::Status(s) => {
                let previous = self.status.replace(s);
                self.event(SessionEvent::Battery {
                    level: s.battery,
                    low: s.battery_low,
                });
                self.buttons(s.buttons, now);
                if previous.is_some_and(|p| p.extension_connected && !s.extension_connected)
                    && self.mp_state == MotionPlusState::Active
                {
                    // Unplugged MotionPlus (or pass-through change): re-probe soon.
                    self.set_mp_state(MotionPlusState::Lost);
                    self.next_mp_probe_us = now;
                }
                // After any status report the remote stops data reports: re-send the mode.
                let r = self.mode_report();
                self.write(r)?;
            }
            InputReport::Ack { report, error, .. } => {
                if self.acks.len() > 32 {
                    self.acks.pop_front();
                }
                self.acks.push_back((report, error));
            }
            InputReport::ReadReply(r) => {
                self.buttons(r.buttons, now);
                self.replies.push_back(r);
            }
            InputReport::Data {
                buttons,
                accel,
                extension,
                ir,
                ..
            } => {
                self.buttons(buttons, now);
                let accel = accel.map(|a| self.accel_cal.to_g(a));
                if let Some(g) = accel.filter(|g| g.is_finite()) {
                    self.last_accel = g;
                }
                if let (Some(ir), Some(IrMode::Basic)) = (ir, self.ir_mode) {
                    match decode_basic(&ir) {
                        Ok(dots) => {
                            if self.config.ir_heading {
                                self.bar_sighting =
                                    Some(IrCamera::default().bar_direction(&dots).ok());
                            }
                            self.event(SessionEvent::Ir {
                                dots,
                                gravity: self.last_accel,
                                timestamp_us: now,
                            })
                        }
                        Err(_) => self.malformed += 1,
                    }
                }
                self.data(now, accel, extension);
            }
        }
        Ok(())
    }

    pub(super) fn buttons(&mut self, b: Buttons, now: u64) {
        if b != self.last_buttons {
            self.last_buttons = b;
            self.event(SessionEvent::Buttons {
                buttons: b,
                timestamp_us: now,
            });
        }
    }

    pub(super) fn data(&mut self, now: u64, accel: Option<DVec3>, ext: Option<[u8; 6]>) {
        let mp_active = self.mp_state == MotionPlusState::Active;
        let mut gyro = None;
        let mut fast = [false; 3];
        if let Some(e) = ext {
            match classify_extension(&e, mp_active) {
                ExtensionData::MotionPlus(f) if mp_active => {
                    self.last_mp_frame_us = now;
                    if self.discard_frames > 0 {
                        self.discard_frames -= 1;
                    } else if let Some(cal) = &self.mp_cal {
                        gyro = Some(cal.rates_deg(&f));
                        fast = [!f.slow[2], !f.slow[1], !f.slow[0]];
                    }
                    let ext_state = if f.extension_connected {
                        if self.extension == ExtensionState::None {
                            ExtensionState::Nunchuk
                        } else {
                            self.extension
                        }
                    } else {
                        ExtensionState::None
                    };
                    self.set_extension(ext_state);
                }
                ExtensionData::Nunchuk(n) if self.extension == ExtensionState::Nunchuk => {
                    self.event(SessionEvent::Nunchuk(n));
                }
                _ => {}
            }
        }
        let Some(accel_g) = accel else { return };
        // dt between estimated sample times (bursts and jitter cost nothing, a lost report is
        // made up; 0 after a dropout). With pass-through frames the gyro updates every other
        // report: its dt spans both.
        let sampled = self.sample_clock.sample_time(now);
        let since = if gyro.is_some() {
            self.last_gyro_s.or(self.last_sample_s)
        } else {
            self.last_sample_s
        };
        let dt = match (sampled, since) {
            (Some(t), Some(since)) => (t - since).clamp(0.0, 0.1),
            _ => 0.0,
        };
        if sampled.is_none() {
            self.last_gyro_s = None;
        }
        self.last_sample_s = sampled;
        if gyro.is_some() {
            self.last_gyro_s = sampled;
        }
        let sample = crate::controllers::fusion::ImuSample {
            timestamp_us: now,
            dt,
            gyro_dps: gyro,
            gyro_fast: fast,
            accel_g,
        };
        self.filter.update(&sample);
        if let Some(bar) = self.bar_sighting.take() {
            self.filter.observe_bar(bar);
        }
        self.event(SessionEvent::Imu(sample));
        let o = OrientationSample {
            timestamp_us: now,
            orientation: self.filter.orientation(),
            angular_velocity: self.filter.angular_velocity(),
            accel_g,
            gyro_fast: fast,
            still: self.filter.is_still(),
            calibration: self.filter.calibration(),
            heading_from_bar: self.filter.heading_from_bar(),
        };
        self.event(SessionEvent::Orientation(o));
    }
}
