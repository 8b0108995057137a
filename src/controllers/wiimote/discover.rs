//! Finding Wii Remotes through hidapi: by Nintendo's vendor and product ids, and by the
//! Bluetooth name for clones that report other ids. Opening one is
//! [`HidTransport::open`](crate::controllers::transport::HidTransport::open).

use super::protocol::{NAME_ORIGINAL, NAME_PLUS, PRODUCT_ID_ORIGINAL, PRODUCT_ID_PLUS, VENDOR_ID};
use crate::controllers::transport::TransportError;

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
