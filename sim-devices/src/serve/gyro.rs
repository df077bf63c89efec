//! A [`Gyro`] (normally [`crate::SimGyro`]) served over a gyro's real wire formats on a byte
//! stream (a [`crate::ports::Pty`]'s server end):
//!
//! - [`serve_slcan`]: an SLCAN USB-CAN adapter with the gyro on its bus. Answers `S`, `O`, `L`,
//!   `C`, `V`, `N`, `F`, `Z0`/`Z1` and transmit commands (`z`/`Z`); while the channel is open
//!   every sample goes out as the bench frame set (delta angle + housekeeping, info frame at
//!   open and about once a second) as `t…\r` lines.
//! - [`serve_kvh1750`]: KVH 1750 format A frames, the gyro's rate as a delta angle on one axis.
//! - [`serve_dsp3000`]: KVH DSP-3000 ASCII lines (rate °/s) or binary rate words.
//!
//! The gyro is sampled all the time (its counter runs even while the channel is closed or the
//! line is silent), so a gap in the output is a gap in the device sequence, as on hardware.
//!
//! Faults ([`FaultSwitch`]), counted per sample:
//! - `Silence`: nothing is sent (SLCAN commands are not answered either);
//! - `Disconnect { seconds }`: silent for that long (bench time), then the fault clears itself;
//! - `Drop { every }`: every n-th sample is not sent (both CAN frames of it);
//! - `Corrupt { every }`: one byte of every n-th sample's output is damaged so that the
//!   receiver can tell: a non-hex character in the delta-angle line (SLCAN), a flipped payload
//!   bit (KVH 1750 → CRC failure, DSP-3000 binary → parity failure), a letter in place of the
//!   decimal point (DSP-3000 ASCII).
//!
//! The functions return only on an I/O error (the port closed); stop them by aborting their task.

use std::io;
use std::sync::Arc;
use std::time::Duration;

use bench_drivers::protocol::gyro_can::{
    status as can_status, DeltaAngle, GyroCanFrame, GyroCanIds, Housekeeping, Info, ANGLE_LSB_EXP,
    PROTOCOL_VERSION,
};
use bench_drivers::protocol::kvh1750;
use bench_drivers::protocol::kvh_dsp3000::{AsciiSample, BinaryWord};
use bench_drivers::protocol::slcan::{AdapterDecoder, AdapterMessage, CanFrame, HostCommand};
use bench_drivers::{Clock, DeviceError, Gyro, GyroSample};
use bench_recording::status;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

use crate::faults::{Fault, FaultCounter, FaultSwitch};

/// What the fault switch says about one sample's output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Action {
    Send,
    /// Withheld by [`Fault::Drop`].
    Skip,
    /// Not sent: the line is dead ([`Fault::Silence`], [`Fault::Disconnect`]).
    Dead,
    Corrupt,
}

/// What became of one sample on a gyro output, as the server knows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Disposition {
    /// Withheld by [`Fault::Drop`].
    Dropped,
    /// Not sent while the line was dead ([`Fault::Silence`], [`Fault::Disconnect`]).
    Silenced,
    /// Sent with a byte damaged by [`Fault::Corrupt`] (the receiver must reject it).
    Corrupted,
}

/// The samples an output sent, by device sequence number: how many went out intact, and the
/// sequence number of each one the fault injector withheld or damaged (only those are kept,
/// so the memory grows with the faults, not with the samples). Samples of a closed SLCAN
/// channel are not counted (nothing is on the wire).
#[derive(Debug, Default)]
pub struct GyroTally(std::sync::Mutex<TallyInner>);

#[derive(Debug, Default, Clone)]
struct TallyInner {
    intact: u64,
    first_seq: Option<u64>,
    last_seq: Option<u64>,
    faulted: Vec<(u64, Disposition)>,
}

/// Counts of a [`GyroTally`] over a range of sequence numbers.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct TallyCounts {
    /// Samples the server handled in the range (sent intact, damaged or withheld).
    pub handled: u64,
    /// Sent intact.
    pub intact: u64,
    /// Withheld by [`Fault::Drop`].
    pub dropped: u64,
    /// Not sent while the line was dead.
    pub silenced: u64,
    /// Sent damaged.
    pub corrupted: u64,
}

impl GyroTally {
    fn lock(&self) -> std::sync::MutexGuard<'_, TallyInner> {
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn note(&self, seq: u64, action: Action) {
        let mut t = self.lock();
        t.first_seq = Some(t.first_seq.map_or(seq, |f| f.min(seq)));
        t.last_seq = Some(t.last_seq.map_or(seq, |l| l.max(seq)));
        match action {
            Action::Send => t.intact += 1,
            Action::Skip => t.faulted.push((seq, Disposition::Dropped)),
            Action::Dead => t.faulted.push((seq, Disposition::Silenced)),
            Action::Corrupt => t.faulted.push((seq, Disposition::Corrupted)),
        }
    }

    /// Sequence numbers of the first and last sample handled.
    pub fn seq_range(&self) -> Option<(u64, u64)> {
        let t = self.lock();
        t.first_seq.zip(t.last_seq)
    }

    /// Counts over sequence numbers `lo..=hi` (the server handles every sample of the gyro in
    /// turn, so every number in the range is one sample).
    pub fn counts_in(&self, lo: u64, hi: u64) -> TallyCounts {
        let t = self.lock();
        let (Some(first), Some(last)) = (t.first_seq, t.last_seq) else {
            return TallyCounts::default();
        };
        let (lo, hi) = (lo.max(first), hi.min(last));
        if lo > hi {
            return TallyCounts::default();
        }
        let mut c = TallyCounts { handled: hi - lo + 1, ..TallyCounts::default() };
        for (seq, d) in &t.faulted {
            if (lo..=hi).contains(seq) {
                match d {
                    Disposition::Dropped => c.dropped += 1,
                    Disposition::Silenced => c.silenced += 1,
                    Disposition::Corrupted => c.corrupted += 1,
                }
            }
        }
        c.intact = c.handled - c.dropped - c.silenced - c.corrupted;
        c
    }

    /// Counts over every sample handled.
    pub fn counts(&self) -> TallyCounts {
        let range = self.seq_range();
        range.map_or_else(TallyCounts::default, |(lo, hi)| self.counts_in(lo, hi))
    }
}

/// Applies a [`FaultSwitch`] sample by sample.
struct FaultGate {
    faults: FaultSwitch,
    clock: Arc<dyn Clock>,
    drops: FaultCounter,
    corrupts: FaultCounter,
    dead_until: Option<Duration>,
}

impl FaultGate {
    fn new(faults: FaultSwitch, clock: Arc<dyn Clock>) -> Self {
        Self {
            faults,
            clock,
            drops: FaultCounter::default(),
            corrupts: FaultCounter::default(),
            dead_until: None,
        }
    }

    /// Whether the line is dead now (silence or a disconnect in progress).
    fn dead(&mut self) -> bool {
        let now = self.clock.now();
        if let Some(Fault::Disconnect { seconds }) =
            self.faults.find(|f| matches!(f, Fault::Disconnect { .. }))
        {
            self.faults.remove(&Fault::Disconnect { seconds });
            let d = Duration::from_secs_f64(seconds.clamp(0.0, 1e6));
            self.dead_until = Some(now + d);
            tracing::info!(seconds, "gyro server: line disconnected");
        }
        if self.dead_until.is_some_and(|t| now >= t) {
            self.dead_until = None;
        }
        self.faults.silent() || self.dead_until.is_some()
    }

    fn action(&mut self) -> Action {
        if self.dead() {
            return Action::Dead;
        }
        if let Some(Fault::Drop { every }) = self.faults.find(|f| matches!(f, Fault::Drop { .. })) {
            if self.drops.tick(every) {
                return Action::Skip;
            }
        }
        if let Some(Fault::Corrupt { every }) =
            self.faults.find(|f| matches!(f, Fault::Corrupt { .. }))
        {
            if self.corrupts.tick(every) {
                return Action::Corrupt;
            }
        }
        Action::Send
    }
}

fn io_err(e: impl std::fmt::Display) -> io::Error {
    io::Error::other(e.to_string())
}

fn sample_err(e: DeviceError) -> io::Error {
    io::Error::other(format!("gyro sample: {e}"))
}

/// How the simulated SLCAN adapter presents itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SlcanAdapterOptions {
    /// Ids of the gyro's frames (default 0x180/0x181/0x182).
    pub ids: GyroCanIds,
    /// `V` answer: hardware, software version (default 0x10, 0x13).
    pub version: (u8, u8),
    /// `N` answer (default `SIM1`).
    pub serial_number: [u8; 4],
}

impl Default for SlcanAdapterOptions {
    fn default() -> Self {
        Self { ids: GyroCanIds::default(), version: (0x10, 0x13), serial_number: *b"SIM1" }
    }
}

/// The two CAN frames of one sample (delta angle first), plus the info frame when due.
pub fn gyro_can_frames(
    s: &GyroSample,
    rate_hz: f64,
    ids: &GyroCanIds,
) -> Result<[CanFrame; 2], bench_drivers::protocol::EncodeError> {
    let seq = s.seq as u32;
    let delta = DeltaAngle::from_rad(seq, s.rate_rad_s / rate_hz)?;
    let mut st = 0u16;
    if s.status & status::gyro::INVALID != 0 {
        st |= can_status::INVALID;
    }
    if s.status & status::gyro::BIT_FAIL != 0 {
        st |= can_status::BIT_FAIL;
    }
    let temp_centi_c = match s.temperature_c {
        Some(t) => Housekeeping::temp_from_c(t)?,
        None => {
            st |= can_status::TEMP_FAULT;
            0
        }
    };
    let house = Housekeeping { seq, status: st, temp_centi_c };
    Ok([
        GyroCanFrame::DeltaAngle(delta).encode(ids)?,
        GyroCanFrame::Housekeeping(house).encode(ids)?,
    ])
}

fn info_frame(rate_hz: f64, ids: &GyroCanIds) -> io::Result<CanFrame> {
    let ns = (1e9 / rate_hz).round().clamp(1.0, f64::from(u32::MAX)) as u32;
    GyroCanFrame::Info(Info {
        sample_period_ns: ns,
        angle_lsb_exp: ANGLE_LSB_EXP,
        version: PROTOCOL_VERSION,
    })
    .encode(ids)
    .map_err(io_err)
}

/// Serve `gyro` as an SLCAN adapter on `port` (see the module docs). `clock` is the bench clock
/// (time stamps with `Z1`, disconnect durations).
pub async fn serve_slcan<G, S>(
    gyro: G,
    port: S,
    options: SlcanAdapterOptions,
    faults: FaultSwitch,
    clock: Arc<dyn Clock>,
) -> io::Result<()>
where
    G: Gyro,
    S: AsyncRead + AsyncWrite + Unpin,
{
    serve_slcan_tallied(gyro, port, options, faults, clock, Arc::default()).await
}

/// [`serve_slcan`], noting what became of every sample of the open channel in `tally`.
pub async fn serve_slcan_tallied<G, S>(
    mut gyro: G,
    mut port: S,
    options: SlcanAdapterOptions,
    faults: FaultSwitch,
    clock: Arc<dyn Clock>,
    tally: Arc<GyroTally>,
) -> io::Result<()>
where
    G: Gyro,
    S: AsyncRead + AsyncWrite + Unpin,
{
    let ids = options.ids;
    let mut gate = FaultGate::new(faults, clock.clone());
    let mut dec = AdapterDecoder::new();
    let mut open = false;
    let mut timestamps = false;
    let mut since_info = 0u64;
    let mut buf = [0u8; 1024];
    let mut out = Vec::with_capacity(256);
    loop {
        tokio::select! {
            r = port.read(&mut buf) => {
                let n = r?;
                if n == 0 {
                    return Err(io::Error::new(io::ErrorKind::UnexpectedEof, "SLCAN host closed"));
                }
                dec.push(buf.get(..n).unwrap_or_default());
                out.clear();
                while let Some(cmd) = dec.next_message() {
                    if gate.dead() {
                        continue;
                    }
                    let reply = match cmd {
                        Err(e) => {
                            tracing::debug!(error = %e, "SLCAN server: bad command");
                            AdapterMessage::Error
                        }
                        Ok(HostCommand::SetBitrate(_) | HostCommand::Timestamps(_)) if open => {
                            AdapterMessage::Error
                        }
                        Ok(HostCommand::SetBitrate(_)) => AdapterMessage::Ok,
                        Ok(HostCommand::Timestamps(on)) => {
                            timestamps = on;
                            AdapterMessage::Ok
                        }
                        Ok(HostCommand::Open | HostCommand::ListenOnly) if open => {
                            AdapterMessage::Error
                        }
                        Ok(HostCommand::Open | HostCommand::ListenOnly) => {
                            open = true;
                            since_info = u64::MAX; // info frame with the first sample
                            AdapterMessage::Ok
                        }
                        Ok(HostCommand::Close) if !open => AdapterMessage::Error,
                        Ok(HostCommand::Close) => {
                            open = false;
                            AdapterMessage::Ok
                        }
                        Ok(HostCommand::Transmit(_)) if !open => AdapterMessage::Error,
                        Ok(HostCommand::Transmit(f)) => {
                            AdapterMessage::TransmitAck { extended: f.id().is_extended() }
                        }
                        Ok(HostCommand::ReadStatus) => AdapterMessage::Status(0),
                        Ok(HostCommand::Version) => AdapterMessage::Version {
                            hardware: options.version.0,
                            software: options.version.1,
                        },
                        Ok(HostCommand::SerialNumber) => {
                            AdapterMessage::Serial(options.serial_number)
                        }
                    };
                    out.extend_from_slice(&reply.encode());
                }
                if !out.is_empty() {
                    port.write_all(&out).await?;
                }
            }
            s = gyro.next_sample() => {
                let s = s.map_err(sample_err)?;
                if !open {
                    continue;
                }
                let action = gate.action();
                tally.note(s.seq, action);
                if matches!(action, Action::Skip | Action::Dead) {
                    continue;
                }
                let rate_hz = gyro.sample_rate_hz();
                let ts = timestamps.then(|| (clock.now().as_millis() % 60_000) as u16);
                let line = |frame: CanFrame| AdapterMessage::Received { frame, timestamp_ms: ts }.encode();
                out.clear();
                since_info = since_info.saturating_add(1);
                if since_info as f64 >= rate_hz {
                    since_info = 0;
                    out.extend_from_slice(&line(info_frame(rate_hz, &ids)?));
                }
                let [delta, house] = gyro_can_frames(&s, rate_hz, &ids).map_err(io_err)?;
                let mut first = line(delta);
                if action == Action::Corrupt {
                    // A non-hex character in the data: the host cannot parse the line.
                    let at = first.len().saturating_sub(3);
                    if let Some(b) = first.get_mut(at) {
                        *b = b'x';
                    }
                }
                out.extend_from_slice(&first);
                out.extend_from_slice(&line(house));
                port.write_all(&out).await?;
            }
        }
    }
}

/// Serve `gyro` as a KVH 1750 (format A, delta angle rad) on `port`: the gyro's rate times the
/// sample period on axis `axis` (0 = x, 1 = y, 2 = z), the other gyro axes 0, accelerometer
/// (0, 0, 1) g, status 0x77 (the sensing axis' valid bit cleared for an invalid sample),
/// sequence = the gyro's counter modulo 128, temperature rounded to 1 °C.
pub async fn serve_kvh1750<G, S>(
    gyro: G,
    port: S,
    axis: usize,
    faults: FaultSwitch,
    clock: Arc<dyn Clock>,
) -> io::Result<()>
where
    G: Gyro,
    S: AsyncRead + AsyncWrite + Unpin,
{
    stream_output(gyro, port, faults, clock, |s, rate_hz, action| {
        let mut gyro_xyz = [0f32; 3];
        if let Some(g) = gyro_xyz.get_mut(axis) {
            *g = (s.rate_rad_s / rate_hz) as f32;
        }
        let mut st = 0x77u8;
        if s.status & status::gyro::INVALID != 0 {
            st &= !kvh1750::STATUS_GYRO_VALID.get(axis).copied().unwrap_or(0);
        }
        let temp = s.temperature_c.unwrap_or(0.0).round();
        let frame = kvh1750::Frame {
            gyro: gyro_xyz,
            accel: [0.0, 0.0, 1.0],
            status: st,
            seq: (s.seq % 128) as u8,
            temp_c: temp.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16,
        };
        let mut bytes = frame.encode().to_vec();
        if action == Action::Corrupt {
            // A flipped payload bit: the CRC no longer matches.
            if let Some(b) = bytes.get_mut(10) {
                *b ^= 0x01;
            }
        }
        Ok(bytes)
    })
    .await
}

/// DSP-3000 output format served by [`serve_dsp3000`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dsp3000Output {
    /// ASCII lines, rate °/s with 6 decimals.
    Ascii,
    /// Binary rate words (60 µ°/s LSB), sync bits 0.
    BinaryRate,
}

/// Serve `gyro` as a KVH DSP-3000 on `port`: one ASCII line or binary word per sample, the
/// rate in °/s, valid unless the sample is flagged invalid.
pub async fn serve_dsp3000<G, S>(
    gyro: G,
    port: S,
    output: Dsp3000Output,
    faults: FaultSwitch,
    clock: Arc<dyn Clock>,
) -> io::Result<()>
where
    G: Gyro,
    S: AsyncRead + AsyncWrite + Unpin,
{
    stream_output(gyro, port, faults, clock, |s, _, action| {
        let valid = s.status & status::gyro::INVALID == 0;
        let rate_deg_s = s.rate_rad_s.to_degrees();
        let mut bytes = match output {
            Dsp3000Output::Ascii => {
                AsciiSample { value: rate_deg_s, valid }.encode().map_err(io_err)?
            }
            Dsp3000Output::BinaryRate => {
                let mut w = BinaryWord::from_rate_deg_s(rate_deg_s, 0).map_err(io_err)?;
                w.valid = valid;
                w.encode().to_vec()
            }
        };
        if action == Action::Corrupt {
            match output {
                Dsp3000Output::Ascii => {
                    if let Some(b) = bytes.iter_mut().find(|b| **b == b'.') {
                        *b = b'x';
                    }
                }
                Dsp3000Output::BinaryRate => {
                    if let Some(b) = bytes.last_mut() {
                        *b ^= 0x01;
                    }
                }
            }
        }
        Ok(bytes)
    })
    .await
}

/// The loop of an output-only gyro (KVH formats): every sample is encoded by `encode` (given
/// the sample, the output rate in Hz and the fault action) and written, unless a fault skips
/// it; whatever the host sends is read and ignored; ends when the host closes the port.
async fn stream_output<G, S>(
    mut gyro: G,
    mut port: S,
    faults: FaultSwitch,
    clock: Arc<dyn Clock>,
    mut encode: impl FnMut(&GyroSample, f64, Action) -> io::Result<Vec<u8>>,
) -> io::Result<()>
where
    G: Gyro,
    S: AsyncRead + AsyncWrite + Unpin,
{
    let mut gate = FaultGate::new(faults, clock);
    let mut sink = [0u8; 256];
    loop {
        tokio::select! {
            r = port.read(&mut sink) => {
                if r? == 0 {
                    return Err(io::Error::new(io::ErrorKind::UnexpectedEof, "host closed"));
                }
            }
            s = gyro.next_sample() => {
                let s = s.map_err(sample_err)?;
                let action = gate.action();
                if matches!(action, Action::Skip | Action::Dead) {
                    continue;
                }
                let bytes = encode(&s, gyro.sample_rate_hz(), action)?;
                port.write_all(&bytes).await?;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_drivers::protocol::gyro_can::SampleAssembler;

    #[test]
    fn a_sample_becomes_the_documented_frame_pair() {
        // The docs' example: sample 0x123456AB, 1 µrad, -40.00 °C (at 20 Hz, rate = 20 µrad/s).
        let s = GyroSample {
            rate_rad_s: 20e-6,
            temperature_c: Some(-40.0),
            seq: 0x1234_56AB,
            status: status::gyro::INVALID,
            device_time: None,
        };
        let ids = GyroCanIds::default();
        let [a, h] = gyro_can_frames(&s, 20.0, &ids).expect("frames");
        assert_eq!(a.data(), &[0xAB, 0xF8, 0xC6, 0x10, 0, 0, 0, 0]);
        assert_eq!(h.data(), &[0xAB, 0x56, 0x34, 0x12, 0x01, 0x00, 0x60, 0xF0]);
        let mut asm = SampleAssembler::new(ids, 0.05);
        assert!(asm.push(&a).is_none());
        let got = asm.push(&h).expect("pair").expect("ok").to_gyro_sample();
        assert_eq!(got.seq, 0x1234_56AB);
        assert_eq!(got.status, status::gyro::INVALID);
        // Half an LSB of delta angle over the 50 ms period.
        let lsb = bench_drivers::protocol::gyro_can::ANGLE_LSB_RAD;
        assert!((got.rate_rad_s - 20e-6).abs() <= 0.5 * lsb * 20.0);
    }
}
