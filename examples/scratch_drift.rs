use bevy_wii_deform::wiimote::{FilterKind, drift};
use glam::DVec3;
fn main() {
    let rec = drift::record_session(1, 600.0);
    for kind in [FilterKind::Fusion, FilterKind::Paper] {
        let mut f = kind.build();
        let mut next = 0.0;
        for (i, s) in rec.samples.iter().enumerate() {
            f.update(s);
            if rec.times[i] >= next {
                next += 10.0;
                let qt = rec.truth[i];
                let qe = f.orientation();
                let tilt = (qt.inverse() * DVec3::Z)
                    .angle_between(qe.inverse() * DVec3::Z)
                    .to_degrees();
                let c = f.calibration();
                let hd = |q: glam::DQuat| {
                    let p = q * DVec3::NEG_Y;
                    p.x.atan2(-p.y).to_degrees()
                };
                println!(
                    "{} yawerr={:7.2} t={:6.1} tilt={:6.2} att={:6.2} still={} bias={:.3?} dt={:.4} g={:.2?} fast={:?}",
                    kind.name(),
                    hd(qe) - hd(qt),
                    rec.times[i],
                    tilt,
                    qt.angle_between(qe).to_degrees(),
                    f.is_still(),
                    c.bias_dps,
                    s.dt,
                    s.gyro_dps.map(|g| g.length()),
                    s.gyro_fast
                );
            }
        }
    }
}
