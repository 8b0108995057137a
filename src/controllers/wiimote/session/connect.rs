//! Connecting: identify, status, accelerometer calibration, the extension and MotionPlus
//! probes, activation and calibration (`PROTOCOL.md` §6–§8).

use super::*;

impl<T: Transport> Session<T> {
    /// Runs the handshake (§6): LEDs, status, accelerometer calibration, MotionPlus probe and
    /// activation, continuous reporting. Errors leave the session disconnected.
    pub fn connect(&mut self) -> Result<RemoteInfo, SessionError> {
        self.connected = false;
        self.mp_state = MotionPlusState::Absent;
        self.mp_cal = None;
        self.leds = 1 << (self.config.player.clamp(1, 4) - 1);
        self.set_leds(self.leds)?;
        self.status = None;
        self.write(OutputReport::StatusRequest {
            rumble: self.rumble,
        })?;
        let deadline = self.now() + self.config.command_timeout_ms as u64 * 1000;
        while self.status.is_none() && self.now() < deadline {
            self.pump(20)?;
        }
        let status = self.status.ok_or(SessionError::Timeout("status"))?;
        let blocks = self.read_memory(AddressSpace::Eeprom, 0x16, 20)?;
        let (accel_cal, valid) = AccelCalibration::from_blocks(&blocks[..10], &blocks[10..20]);
        self.accel_cal = accel_cal;
        self.mode = 0x31;
        self.command(self.mode_report())?;
        let mut crc_ok = false;
        match self.probe_motion_plus() {
            Ok(ok) => crc_ok = ok,
            Err(e @ SessionError::UnsupportedDevice(_)) => return Err(e),
            Err(e @ SessionError::Transport(_)) => return Err(e),
            Err(_) => self.set_mp_state(MotionPlusState::Absent),
        }
        if self.mp_state != MotionPlusState::Active {
            self.probe_extension()?;
        }
        self.mode = self.streaming_mode();
        self.command(self.mode_report())?;
        self.connected = true;
        if let Some(sensitivity) = self.config.ir_camera {
            // A camera that does not answer leaves it off: posing with the MotionPlus goes on.
            let _ = self.enable_ir(IrMode::Basic, sensitivity);
        }
        let now = self.now();
        self.last_battery_us = now;
        self.last_mp_frame_us = now;
        self.next_mp_probe_us = now + self.config.motion_plus_poll_ms as u64 * 1000;
        Ok(RemoteInfo {
            kind: self.kind,
            accel_calibration: accel_cal,
            accel_calibration_valid: valid,
            motion_plus_calibration: self.mp_cal,
            motion_plus_crc_ok: crc_ok,
            motion_plus: self.mp_state,
            battery: status.battery,
        })
    }

    pub(super) fn set_mp_state(&mut self, s: MotionPlusState) {
        if self.mp_state != s {
            self.mp_state = s;
            self.event(SessionEvent::MotionPlus(s));
        }
    }

    pub(super) fn read_id(&mut self, address: u32) -> Result<ExtensionId, SessionError> {
        let id = self.read_memory(AddressSpace::Registers, address, 6)?;
        Ok(ExtensionId::parse(&id))
    }

    pub(super) fn probe_extension(&mut self) -> Result<(), SessionError> {
        let plugged = self.status.is_some_and(|s| s.extension_connected);
        if !plugged {
            self.set_extension(ExtensionState::None);
            return Ok(());
        }
        let _ = self.command(OutputReport::write_register(0xA400F0, 0x55, self.rumble));
        let _ = self.command(OutputReport::write_register(0xA400FB, 0x00, self.rumble));
        match self.read_id(0xA400FA) {
            Ok(ExtensionId::BalanceBoard) => Err(SessionError::UnsupportedDevice("Balance Board")),
            Ok(ExtensionId::ProController) => {
                Err(SessionError::UnsupportedDevice("Wii U Pro Controller"))
            }
            Ok(ExtensionId::Nunchuk) => {
                self.set_extension(ExtensionState::Nunchuk);
                Ok(())
            }
            Ok(_) => {
                self.set_extension(ExtensionState::Other);
                Ok(())
            }
            Err(SessionError::Transport(e)) => Err(e.into()),
            Err(_) => Ok(()),
        }
    }

    pub(super) fn set_extension(&mut self, e: ExtensionState) {
        if self.extension != e {
            self.extension = e;
            self.event(SessionEvent::Extension(e));
        }
    }

    /// Finds, calibrates and activates a MotionPlus (§8). Returns whether its calibration
    /// CRC matched.
    pub(super) fn probe_motion_plus(&mut self) -> Result<bool, SessionError> {
        let init = self.command(OutputReport::write_register(0xA600F0, 0x55, self.rumble));
        let inactive = match init {
            Ok(()) => matches!(
                self.read_id(0xA600FA),
                Ok(ExtensionId::MotionPlus { active: false, .. })
            ),
            Err(SessionError::Remote { code: 7, .. }) => false,
            Err(e) => return Err(e),
        };
        let id_first_byte_plus = |s: &mut Self, addr: u32| -> Result<bool, SessionError> {
            let id = s.read_memory(AddressSpace::Registers, addr, 6)?;
            Ok(id.first() == Some(&0x01))
        };
        if !inactive {
            // Absent or already active.
            return match self.read_id(0xA400FA) {
                Ok(ExtensionId::MotionPlus { active: true, mode }) => {
                    if id_first_byte_plus(self, 0xA400FA)? {
                        self.kind = RemoteKind::Plus;
                    }
                    self.mp_mode = mode;
                    let ok = self.read_mp_calibration(0xA40020)?;
                    self.discard_frames = 2;
                    self.set_mp_state(MotionPlusState::Active);
                    Ok(ok)
                }
                Ok(ExtensionId::BalanceBoard) => {
                    Err(SessionError::UnsupportedDevice("Balance Board"))
                }
                Ok(ExtensionId::ProController) => {
                    Err(SessionError::UnsupportedDevice("Wii U Pro Controller"))
                }
                _ => {
                    self.set_mp_state(MotionPlusState::Absent);
                    Ok(false)
                }
            };
        }
        if id_first_byte_plus(self, 0xA600FA)? {
            self.kind = RemoteKind::Plus;
        }
        // Pass-through: a Nunchuk behind the MotionPlus selects mode 0x05.
        self.mp_mode = 0x04;
        if self.status.is_some_and(|s| s.extension_connected) {
            self.probe_extension()?;
            if self.extension == ExtensionState::Nunchuk {
                self.mp_mode = 0x05;
            }
        }
        let crc_ok = self.read_mp_calibration(0xA60020)?;
        self.set_mp_state(MotionPlusState::Activating);
        for attempt in 0..3 {
            if attempt > 0 {
                self.wait(1000)?;
            }
            if self
                .command(OutputReport::write_register(
                    0xA600FE,
                    self.mp_mode,
                    self.rumble,
                ))
                .is_err()
            {
                continue;
            }
            self.wait(self.config.activation_wait_ms)?;
            self.command(self.mode_report())?;
            if let Ok(ExtensionId::MotionPlus { active: true, .. }) = self.read_id(0xA400FA) {
                self.discard_frames = 2;
                self.last_mp_frame_us = self.now();
                self.set_mp_state(MotionPlusState::Active);
                return Ok(crc_ok);
            }
        }
        self.set_mp_state(MotionPlusState::Lost);
        Err(SessionError::Timeout("MotionPlus activation"))
    }

    pub(super) fn read_mp_calibration(&mut self, address: u32) -> Result<bool, SessionError> {
        for _ in 0..2 {
            let bytes = self.read_memory(AddressSpace::Registers, address, 32)?;
            if let Ok((cal, true)) = MotionPlusCalibration::parse(&bytes) {
                self.mp_cal = Some(cal);
                return Ok(true);
            }
        }
        self.mp_cal = Some(MotionPlusCalibration::fallback());
        Ok(false)
    }
}
