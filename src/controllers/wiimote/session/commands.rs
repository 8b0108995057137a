//! Talking to the remote: writes with retries, acknowledged commands, memory reads, LEDs,
//! rumble and the IR camera's initialisation (`PROTOCOL.md` §3–§4, §17).

use super::*;

impl<T: Transport> Session<T> {
    /// Sets the rumble motor (carried in every later report too).
    pub fn set_rumble(&mut self, on: bool) -> Result<(), SessionError> {
        self.rumble = on;
        self.write(OutputReport::Rumble { rumble: on })
    }

    /// Sets the player LEDs (bit 0 = LED1).
    pub fn set_leds(&mut self, leds: u8) -> Result<(), SessionError> {
        self.leds = leds & 0x0F;
        self.command(OutputReport::Leds {
            leds: self.leds,
            ack: true,
            rumble: self.rumble,
        })
    }

    /// Turns the IR camera on (`PROTOCOL.md` §17.2: pixel clock, logic, control, the two
    /// sensitivity blocks, the mode, control again) and reads the mode register back. A
    /// remote whose camera does not answer gives [`SessionError::Camera`]; the session keeps
    /// running (MotionPlus posing is unaffected), so a caller can carry on without a pointer.
    pub fn enable_ir(
        &mut self,
        mode: IrMode,
        sensitivity: IrSensitivity,
    ) -> Result<(), SessionError> {
        let camera = |e: SessionError| SessionError::Camera(Box::new(e));
        for step in ir_init_sequence(mode, sensitivity) {
            let report = match step {
                IrInitStep::Enable { report } => OutputReport::Flag {
                    id: report,
                    enable: true,
                    ack: true,
                    rumble: self.rumble,
                },
                IrInitStep::Write { address, bytes } => OutputReport::WriteMemory {
                    space: AddressSpace::Registers,
                    address,
                    data: bytes,
                    rumble: self.rumble,
                },
            };
            self.command(report).map_err(camera)?;
        }
        let read = self
            .read_memory(AddressSpace::Registers, IR_MODE_REGISTER, 1)
            .map_err(camera)?;
        if read.first() != Some(&mode.register_value()) {
            return Err(SessionError::Camera(Box::new(SessionError::Timeout(
                "the IR mode register to read back its mode",
            ))));
        }
        self.ir_mode = Some(mode);
        if self.connected {
            self.mode = self.streaming_mode();
            self.command(self.mode_report()).map_err(camera)?;
        }
        Ok(())
    }

    /// The data report streamed: 0x37 (buttons, accelerometer, 10 bytes of basic IR, 6 of
    /// extension) once the camera runs in basic mode, else 0x35. Extended and full IR need
    /// reports with no room for the MotionPlus, so they are initialised but not streamed.
    pub(super) fn streaming_mode(&self) -> u8 {
        match self.ir_mode {
            Some(IrMode::Basic) => 0x37,
            _ => 0x35,
        }
    }

    /// Writes one report, honouring the write spacing; never waits for an answer.
    pub(super) fn write(&mut self, report: OutputReport) -> Result<(), SessionError> {
        if let Some(last) = self.last_write_us {
            let due = last + self.config.write_spacing_ms as u64 * 1000;
            while self.now() < due {
                let ms = ((due - self.now()) / 1000).max(1) as u32;
                self.pump(ms)?;
            }
        }
        let bytes = report.with_rumble(self.rumble).encode();
        self.transport.write(&bytes)?;
        self.last_write_us = Some(self.now());
        Ok(())
    }

    pub(super) fn mode_report(&self) -> OutputReport {
        OutputReport::ReportMode {
            mode: self.mode,
            continuous: true,
            ack: true,
            rumble: self.rumble,
        }
    }

    /// Sends a report with the ack bit and waits for its 0x22; retries on timeout and on
    /// busy/unknown error codes.
    pub(super) fn command(&mut self, report: OutputReport) -> Result<(), SessionError> {
        let id = report.encode()[0];
        let mut last_error = None;
        for _ in 0..=self.config.retries {
            self.acks.clear();
            self.write(report.clone())?;
            let deadline = self.now() + self.config.command_timeout_ms as u64 * 1000;
            loop {
                if let Some(pos) = self.acks.iter().position(|(r, _)| *r == id) {
                    let (_, code) = self.acks.remove(pos).expect("position is valid");
                    match code {
                        0 => return Ok(()),
                        6..=8 => return Err(SessionError::Remote { report: id, code }),
                        _ => {
                            last_error = Some(SessionError::Remote { report: id, code });
                            break;
                        }
                    }
                }
                let now = self.now();
                if now >= deadline {
                    break;
                }
                self.pump(((deadline - now) / 1000).clamp(1, 50) as u32)?;
            }
        }
        Err(last_error.unwrap_or(SessionError::Timeout("command")))
    }

    /// Reads `size` bytes of memory, collecting the 0x21 replies.
    pub(super) fn read_memory(
        &mut self,
        space: AddressSpace,
        address: u32,
        size: u16,
    ) -> Result<Vec<u8>, SessionError> {
        for _ in 0..=self.config.retries {
            self.replies.clear();
            self.acks.clear();
            self.write(OutputReport::ReadMemory {
                space,
                address,
                size,
                rumble: self.rumble,
            })?;
            let deadline = self.now() + self.config.command_timeout_ms as u64 * 1000;
            let mut data = Vec::with_capacity(size as usize);
            let mut retry = false;
            while data.len() < size as usize {
                if let Some(r) = self.replies.pop_front() {
                    if r.error != 0 {
                        if matches!(r.error, 6..=8) {
                            return Err(SessionError::Remote {
                                report: 0x17,
                                code: r.error,
                            });
                        }
                        retry = true;
                        break;
                    }
                    data.extend_from_slice(&r.data);
                    continue;
                }
                if self.acks.iter().any(|(r, c)| *r == 0x17 && *c != 0) {
                    retry = true; // busy
                    break;
                }
                let now = self.now();
                if now >= deadline {
                    retry = true;
                    break;
                }
                self.pump(((deadline - now) / 1000).clamp(1, 50) as u32)?;
            }
            if !retry {
                data.truncate(size as usize);
                return Ok(data);
            }
            // Let a running read finish before asking again.
            let settle = self.now() + 100_000;
            while self.now() < settle {
                self.pump(20)?;
            }
        }
        Err(SessionError::Timeout("memory read"))
    }

    pub(super) fn wait(&mut self, ms: u32) -> Result<(), SessionError> {
        let until = self.now() + ms as u64 * 1000;
        while self.now() < until {
            let left = ((until - self.now()) / 1000).clamp(1, 50) as u32;
            self.pump(left)?;
        }
        Ok(())
    }
}
