"""Independent peer of a gyro on a Lawicel SLCAN adapter, on a pseudo-terminal.

python-can's `slcan` interface is a HOST-side client (it writes S6/O and reads frames; it never
answers commands), so it cannot play the adapter. This program therefore IS the adapter, written
from the Lawicel text protocol, with a gyro behind it that sends bench's CAN frame set as
docs/protocols/gyro-can.md describes it (implemented here from that document, not from bench's
Rust). python-can's `slcan` interface is used as an independent CLIENT of this adapter in
check_slcan_python_can.py.

Lawicel: every command ends in "\\r"; success is "\\r", error BEL (0x07). S0..S8 bit rate (only
while closed), O open, L listen only, C close, tiiildd.. / Tiiiiiiiildd.. transmit (answered
"z\\r" / "Z\\r"), F status flags ("Fxx\\r", open only), V version ("Vhhss\\r"), N serial number
("Nxxxx\\r"), Z0/Z1 time stamps off/on (only while closed; when on, each received frame carries
4 hex digits of milliseconds 0..59999). Anything else: BEL.

Gyro frames (11-bit ids, DLC 8, little-endian): 0x180 delta angle = sequence low byte, signed
56-bit delta angle, LSB 2^-40 rad; 0x181 housekeeping = u32 sequence, u16 status (bit 0 invalid,
1 BIT failure, 2 over-range, 3 temperature sensor fault), i16 temperature 0.01 degC; 0x182 info =
u32 sample period ns, u8 LSB exponent 40, u8 protocol version 1, 2 reserved bytes, sent before
the first sample after opening and then once per second of samples. Each sample: 0x180 then
0x181.

The gyro's counter runs from --seq0 at --rate-hz of bench time whether or not the channel is
open; frames go out only while it is open. Every command and every sample sent is logged.

Coupled (--table-state and --chamber-state, the state files table.py --state and chamber.py
--state publish): the gyro is a FOG with its sensing axis up on the table peer's axis, inside the
chamber peer's air, with the linear thermal error model of the seed study (docs/seed-method.md):

    output = (1 + scale_factor_error)(input + earth) + bias + temp_coeff (T - T0)
             + temp_rate_coeff dT/dt + noise

input = the table's angle increment over the sample interval / the interval (the angle at each
sample's nominal time, carried on from the table's last published state with its own slew
kinematics), earth = Omega_E sin(latitude), T the gyro's own temperature (a first-order lag of
thermal_time_constant behind the air; its mean over the interval, dT/dt its exact mean), noise
white (arw / sqrt(interval)) plus a first-order Gauss-Markov bias instability (correlation time
100 s, its Allan deviation peaking near bias_instability). The coefficients come from --model
(a JSON object with the `bench.gyro_model` keys, SI units), the noise from --seed. The delta
angle's rounding to the LSB is carried to the next sample, so no angle is lost. The temperature
is sent in 0.01 degC. --bit-fail-after S sets the built-in-test bit on every sample from S
bench seconds on.
"""

from __future__ import annotations

import asyncio
import json
import math
import random

import peerlib
import table as table_peer

LSB_EXP = 40
BITRATES = {f"S{i}": r for i, r in enumerate(
    [10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000])}


def frame_line(can_id: int, data: bytes, stamp_ms: int | None) -> str:
    line = f"t{can_id:03X}{len(data)}{data.hex().upper()}"
    if stamp_ms is not None:
        line += f"{stamp_ms % 60000:04X}"
    return line + "\r"


def delta_frame(seq: int, delta_lsb: int) -> bytes:
    if not -(1 << 55) <= delta_lsb < (1 << 55):
        raise ValueError("delta angle outside 56 bits")
    return bytes([seq & 0xFF]) + (delta_lsb & ((1 << 56) - 1)).to_bytes(7, "little")


def housekeeping_frame(seq: int, status: int, temp_centi: int) -> bytes:
    return (
        (seq & 0xFFFFFFFF).to_bytes(4, "little")
        + status.to_bytes(2, "little")
        + temp_centi.to_bytes(2, "little", signed=True)
    )


def info_frame(period_ns: int) -> bytes:
    return period_ns.to_bytes(4, "little") + bytes([LSB_EXP, 1, 0, 0])


class Gyro:
    """The signal: rate = base + slope x k rad/s, temperature 25 degC + 0.01 degC x k; with
    --status-demo some samples carry status bits (see `status`)."""

    def __init__(self, rate_hz: float, seq0: int, base: float, status_demo: bool,
                 bit_fail_after: float | None = None) -> None:
        self.period_ns = round(1e9 / rate_hz)
        self.period_s = self.period_ns * 1e-9
        self.seq0 = seq0
        self.base = base
        self.status_demo = status_demo
        self.bit_fail_after = bit_fail_after

    def sample(self, k: int) -> dict:
        rate = self.base + 1e-7 * (k % 50)
        delta = round(rate * self.period_s * 2.0**LSB_EXP)
        status = 0
        if self.status_demo:
            status = {3: 0x0001, 5: 0x0002, 7: 0x0004, 9: 0x0008}.get(k % 10, 0)
        if self.bit_fail_after is not None and k * self.period_s >= self.bit_fail_after:
            status |= 0x0002
        return {
            "seq": (self.seq0 + k) & 0xFFFFFFFF,
            "delta": delta,
            "status": status,
            "temp_centi": 2500 + k % 1000,
            "period_ns": self.period_ns,
        }


EARTH_RATE_RAD_S = 7.2921150e-5


class CoupledGyro:
    """A FOG on the table peer's axis in the chamber peer's air (see the module's text)."""

    def __init__(self, rate_hz: float, seq0: int, clock: peerlib.Clock, table_state: str,
                 chamber_state: str, model: dict, latitude_deg: float, initial_temp_c: float,
                 seed: int, bit_fail_after: float | None) -> None:
        self.period_ns = round(1e9 / rate_hz)
        self.period_s = self.period_ns * 1e-9
        self.seq0 = seq0
        self.clock = clock
        self.table_state = table_state
        self.chamber_state = chamber_state
        self.m = {k: float(v) for k, v in model.items()}
        earth = EARTH_RATE_RAD_S * math.sin(math.radians(latitude_deg))
        self.earth = earth if self.m.get("earth_rate", 1.0) != 0 else 0.0
        self.temp = initial_temp_c
        self.rng = random.Random(seed)
        self.gm_tau = 100.0
        self.gm_sigma = self.m.get("bias_instability", 0.0) / 0.62
        self.gm = self.rng.gauss(0.0, self.gm_sigma)
        self.theta = None  # rad, the table's angle at the last sample
        self.residue = 0.0  # rad not yet sent (rounding to the LSB)
        self.bit_fail_after = bit_fail_after

    def table_angle_rad(self, mono: float) -> float:
        st = peerlib.StateFile.read(self.table_state)
        if st is None:
            return 0.0 if self.theta is None else self.theta
        dt = (mono - st["mono"]) * self.clock.scale
        if dt >= 0 and st.get("moving_to") is None:
            angle, _, _ = table_peer.advance(st["angle_deg"], st["rate_deg_s"],
                                             st["rate_cmd_deg_s"], st["accel_deg_s2"], dt)
        else:
            # A state published after the sample's time (a late wake-up): back at its rate.
            angle = st["angle_deg"] + st["rate_deg_s"] * dt
        return math.radians(angle)

    def air_c(self) -> float:
        st = peerlib.StateFile.read(self.chamber_state)
        return self.temp if st is None else st["air_c"]

    def sample(self, k: int, mono: float) -> dict:
        """Sample k, whose interval ends at host monotonic time `mono` (its nominal time)."""
        m, dt = self.m, self.period_s
        theta = self.table_angle_rad(mono)
        d_theta = 0.0 if self.theta is None else theta - self.theta
        self.theta = theta
        t0 = self.temp
        tau = m.get("thermal_time_constant", 0.0)
        air = self.air_c()
        self.temp = air + (t0 - air) * math.exp(-dt / tau) if tau > 0 else air
        t_mean = 0.5 * (t0 + self.temp)
        rate_in = d_theta / dt + self.earth
        a = math.exp(-dt / self.gm_tau)
        self.gm = self.gm * a + self.gm_sigma * math.sqrt(1.0 - a * a) * self.rng.gauss(0, 1)
        rate = (rate_in * (1.0 + m.get("scale_factor_error", 0.0))
                + m.get("bias", 0.0)
                + m.get("temp_coeff", 0.0) * (t_mean - m.get("reference_temperature", 20.0))
                + m.get("temp_rate_coeff", 0.0) * (self.temp - t0) / dt
                + m.get("arw", 0.0) / math.sqrt(dt) * self.rng.gauss(0, 1)
                + self.gm)
        angle = rate * dt + self.residue
        delta = round(angle * 2.0**LSB_EXP)
        self.residue = angle - delta * 2.0**-LSB_EXP
        failing = self.bit_fail_after is not None and k * dt >= self.bit_fail_after
        return {
            "seq": (self.seq0 + k) & 0xFFFFFFFF,
            "delta": delta,
            "status": 0x0002 if failing else 0,
            "temp_centi": round(self.temp * 100),
            "period_ns": self.period_ns,
            "table_rad": theta,
            "air_c": air,
        }


class Adapter:
    def __init__(self, stream: peerlib.PtyStream, gyro: Gyro, clock: peerlib.Clock,
                 log: peerlib.Log) -> None:
        self.stream = stream
        self.gyro = gyro
        self.clock = clock
        self.log = log
        self.open = False
        self.stamps = False
        self.bitrate = None
        self.info_due = True

    def answer(self, cmd: str) -> str:
        c = cmd[:1]
        closed_only = {"S", "Z"}
        if cmd in BITRATES and not self.open:
            self.bitrate = BITRATES[cmd]
            return "\r"
        if cmd in ("Z0", "Z1") and not self.open:
            self.stamps = cmd == "Z1"
            return "\r"
        if c in closed_only:
            return "\a"
        if cmd in ("O", "L"):
            if self.open:
                return "\a"
            self.open = True
            self.info_due = True
            return "\r"
        if cmd == "C":
            if not self.open:
                return "\a"
            self.open = False
            return "\r"
        if cmd == "F":
            return "F00\r" if self.open else "\a"
        if cmd == "V":
            return "V1013\r"
        if cmd == "N":
            return "NA123\r"
        if c in ("t", "T", "r", "R"):
            if not self.open:
                return "\a"
            return "z\r" if c in ("t", "r") else "Z\r"
        return "\a"

    async def commands(self) -> None:
        buf = bytearray()
        while True:
            buf += await self.stream.read()
            while (i := buf.find(b"\r")) >= 0:
                cmd = buf[:i].decode("ascii", errors="replace")
                del buf[: i + 1]
                reply = self.answer(cmd)
                self.log.write(rx=cmd, tx=reply.replace("\a", "BEL").replace("\r", ""))
                self.stream.write(reply.encode("ascii"))

    async def samples(self) -> None:
        g = self.gyro
        k = 0
        while True:
            due = k * g.period_s
            wait = self.clock.wall(due - self.clock.now())
            if wait > 0:
                await asyncio.sleep(wait)
            if isinstance(g, CoupledGyro):
                s = g.sample(k, self.clock.mono(due))
            else:
                s = g.sample(k)
            k += 1
            if not self.open:
                continue
            stamp = int(self.clock.now() * 1000) if self.stamps else None
            out = ""
            if self.info_due or k % max(1, round(1.0 / g.period_s)) == 0:
                out += frame_line(0x182, info_frame(g.period_ns), stamp)
                self.info_due = False
            out += frame_line(0x180, delta_frame(s["seq"], s["delta"]), stamp)
            out += frame_line(0x181, housekeeping_frame(s["seq"], s["status"], s["temp_centi"]),
                              stamp)
            self.stream.write(out.encode("ascii"))
            self.log.write(sample=s)


async def main() -> None:
    p = peerlib.base_args(__doc__.splitlines()[0])
    p.add_argument("--rate-hz", type=float, default=20.0, help="sample rate, bench Hz")
    p.add_argument("--seq0", type=lambda s: int(s, 0), default=0, help="first sequence number")
    p.add_argument("--rate-rad-s", type=float, default=7.2921e-5 * math.sin(math.radians(45)),
                   help="base rate, rad/s")
    p.add_argument("--status-demo", action="store_true",
                   help="samples k%%10 = 3, 5, 7, 9 carry status bits 0, 1, 2, 3")
    p.add_argument("--table-state", help="coupled: the table peer's state file")
    p.add_argument("--chamber-state", help="coupled: the chamber peer's state file")
    p.add_argument("--model", default="{}",
                   help="coupled: the gyro model, JSON with bench.gyro_model keys (SI)")
    p.add_argument("--latitude-deg", type=float, default=45.0, help="coupled: site latitude")
    p.add_argument("--initial-temp-c", type=float, default=20.0,
                   help="coupled: the gyro's temperature at start")
    p.add_argument("--seed", type=int, default=1, help="coupled: noise seed")
    p.add_argument("--bit-fail-after", type=float, metavar="S",
                   help="set the built-in-test bit on every sample from S bench seconds on")
    args = p.parse_args()
    clock = peerlib.Clock(args.time_scale)
    log = peerlib.Log(args.log, clock)
    pty = peerlib.Pty()
    if args.table_state or args.chamber_state:
        if not (args.table_state and args.chamber_state):
            p.error("coupling needs both --table-state and --chamber-state")
        gyro = CoupledGyro(args.rate_hz, args.seq0, clock, args.table_state, args.chamber_state,
                           json.loads(args.model), args.latitude_deg, args.initial_temp_c,
                           args.seed, args.bit_fail_after)
    else:
        gyro = Gyro(args.rate_hz, args.seq0, args.rate_rad_s, args.status_demo,
                    args.bit_fail_after)
    adapter = Adapter(peerlib.PtyStream(pty), gyro, clock, log)
    tasks = [asyncio.create_task(adapter.commands()), asyncio.create_task(adapter.samples())]
    peerlib.ready("gyro-slcan", pty=pty.path)
    await peerlib.run_until_stdin_closes(*tasks)


if __name__ == "__main__":
    asyncio.run(main())
