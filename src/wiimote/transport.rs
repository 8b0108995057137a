//! The byte transport under a session: hidapi for real remotes, or the emulator.

/// Transport failures.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TransportError {
    /// The remote is gone (powered off, out of range, unpaired).
    #[error("the remote disconnected")]
    Disconnected,
    /// Another I/O error (message from the OS / hidapi).
    #[error("I/O error: {0}")]
    Io(String),
    /// The device node could not be opened.
    #[error("cannot open {node}: {kind:?}")]
    Open {
        /// Device node.
        node: String,
        /// Why.
        kind: super::diagnosis::OpenErrorKind,
    },
}

/// Raw HID report I/O with a clock. One transport per remote, used from one I/O thread.
pub trait Transport: Send {
    /// Writes one output report (report id first). Returns bytes written.
    fn write(&mut self, report: &[u8]) -> Result<usize, TransportError>;
    /// Reads one input report into `buf` (report id first), waiting at most `timeout_ms`.
    /// Returns 0 on timeout.
    fn read_timeout(&mut self, buf: &mut [u8], timeout_ms: u32) -> Result<usize, TransportError>;
    /// Microseconds on this transport's clock (wall clock for hardware, virtual for the
    /// emulator), used to timestamp samples.
    fn now_us(&self) -> u64;
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn write(&mut self, report: &[u8]) -> Result<usize, TransportError> {
        (**self).write(report)
    }
    fn read_timeout(&mut self, buf: &mut [u8], timeout_ms: u32) -> Result<usize, TransportError> {
        (**self).read_timeout(buf, timeout_ms)
    }
    fn now_us(&self) -> u64 {
        (**self).now_us()
    }
}

#[cfg(feature = "hidapi")]
pub use hid::*;

#[cfg(feature = "hidapi")]
mod hid {
    use std::time::Instant;

    use super::{Transport, TransportError};
    use crate::wiimote::protocol::{
        NAME_ORIGINAL, NAME_PLUS, PRODUCT_ID_ORIGINAL, PRODUCT_ID_PLUS, VENDOR_ID,
    };

    /// A remote found by [`discover`].
    #[derive(Debug, Clone, PartialEq, Eq)]
    pub struct DeviceInfo {
        /// OS path (e.g. `/dev/hidraw3`).
        pub path: String,
        /// USB/Bluetooth product id.
        pub product_id: u16,
        /// Product string, if readable.
        pub product: Option<String>,
        /// Serial (Bluetooth address), if readable.
        pub serial: Option<String>,
    }

    /// Lists Wii Remotes (by VID/PID and by product string, for clones).
    pub fn discover() -> Result<Vec<DeviceInfo>, TransportError> {
        let api = hidapi::HidApi::new().map_err(|e| TransportError::Io(e.to_string()))?;
        let mut out: Vec<DeviceInfo> = Vec::new();
        for d in api.device_list() {
            let product = d.product_string().map(str::to_string);
            let by_name = matches!(product.as_deref(), Some(NAME_ORIGINAL) | Some(NAME_PLUS));
            let by_id = d.vendor_id() == VENDOR_ID
                && (d.product_id() == PRODUCT_ID_ORIGINAL || d.product_id() == PRODUCT_ID_PLUS);
            let path = d.path().to_string_lossy().into_owned();
            if (by_name || by_id) && !out.iter().any(|o| o.path == path) {
                out.push(DeviceInfo {
                    path,
                    product_id: d.product_id(),
                    product,
                    serial: d.serial_number().map(str::to_string),
                });
            }
        }
        Ok(out)
    }

    /// A remote opened through hidapi.
    pub struct HidTransport {
        device: hidapi::HidDevice,
        epoch: Instant,
    }

    impl HidTransport {
        /// Opens the device at `path`. A node that cannot be opened gives
        /// [`TransportError::Open`] with the OS's reason (hidapi's own error is only a message,
        /// so the node is probed first).
        pub fn open(path: &str) -> Result<Self, TransportError> {
            #[cfg(target_os = "linux")]
            if let Err(kind) = crate::wiimote::diagnosis::probe_open(std::path::Path::new(path)) {
                return Err(TransportError::Open {
                    node: path.to_string(),
                    kind,
                });
            }
            let api = hidapi::HidApi::new().map_err(|e| TransportError::Io(e.to_string()))?;
            let cpath =
                std::ffi::CString::new(path).map_err(|e| TransportError::Io(e.to_string()))?;
            let device = api
                .open_path(&cpath)
                .map_err(|e| TransportError::Io(e.to_string()))?;
            Ok(Self {
                device,
                epoch: Instant::now(),
            })
        }
    }

    impl Transport for HidTransport {
        fn write(&mut self, report: &[u8]) -> Result<usize, TransportError> {
            self.device
                .write(report)
                .map_err(|_| TransportError::Disconnected)
        }
        fn read_timeout(
            &mut self,
            buf: &mut [u8],
            timeout_ms: u32,
        ) -> Result<usize, TransportError> {
            self.device
                .read_timeout(buf, timeout_ms.min(i32::MAX as u32) as i32)
                .map_err(|_| TransportError::Disconnected)
        }
        fn now_us(&self) -> u64 {
            self.epoch.elapsed().as_micros() as u64
        }
    }
}
