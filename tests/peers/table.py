"""Independent peers of the rate-table controllers: Actidyn (TCP or pty) and Acutronic ACUTROL
(TCP), with one simulated axis.

Written from the public facts only (docs/protocols/peers.md quotes them), not from bench's
codecs:

Actidyn: ASCII, a request line ends in "\\n"; commands chained with ":"; arguments separated by
"," with the axis first ("&" = all axes). RMT 0 remote, LOC 0 local, ALC 0 clear alarms (the
drive switches off when alarms are not cleared within 30 s: --watchdog-s); MOD <ax>,1 servo on,
OFF, POS, RAT, SIN, STP stop, MOD <ax>,? mode; POS <ax>,<deg>,<deg/s>; RAT <ax>,<deg/s>,<deg/s2>;
POS <ax>,? and PRV <ax>,? (position, rate, acceleration). A reply echoes the command, then a
value count, then the values. Where the facts are silent the peer picks one reading and says so:
  --echo short (default): the echo is the mnemonic and the axis: "PRV 1,3,p,r,a", "RAT 1,0";
  --echo full: the echo is the whole command: "PRV 1,?,3,p,r,a", "RAT 1,10,1,0".
Replies to chained commands are chained with ":" in the same order. Refusals: "<MNE> <ax>,ERR,
<code>,<text>" (the codes are the peer's own; the facts give none).

ACUTROL: SCPI-like lines ending "\\r\\n"; ":utility:lockout on", ":interlock:open|reset|close 1",
":mode:off|rate|position 1", ":demand:rate 1, <deg/s>", ":demand:position 1, <deg>",
":read:rate 1", ":read:position 1"; short forms ":M:R 1", ":D:R 1, <v>", ":R:R 1", ":R:P 1".
Set commands are answered "OK"; reads with the number. Anything else: "ERR <text>".

Physics (bench time): the rate slews to the command at the commanded acceleration, the angle
integrates; a stop decelerates at --stop-decel. The angle is reported wrapped to [0, 360).

Faults (Actidyn): --watchdog-s (the keep-alive's limit) and --drive-trip-after-rat S (a drive
alarm S bench seconds after the first rate command that moves the table): the drive switches
off, the axis decelerates, MOD ? reads OFF, and mode and motion commands are refused (code 4)
until ALC 0; each drop is logged as {"event": "watchdog" | "drive_trip"}.

Coupling: --state FILE publishes the axis state (peerlib.StateFile) for gyro.py --table-state.
"""

from __future__ import annotations

import asyncio
import math
import re

import peerlib


def advance(angle: float, rate: float, rate_cmd: float, accel: float,
            dt: float) -> tuple[float, float, float]:
    """`dt` seconds of the rate loop: the rate slews to `rate_cmd` at `accel` (deg/s2, 0 = at
    once), the angle integrates exactly. Returns (angle deg, rate deg/s, acceleration now)."""
    d = rate_cmd - rate
    need = abs(d) / accel if accel > 0 else 0.0
    if need >= dt:
        a = math.copysign(accel, d)
        return angle + rate * dt + 0.5 * a * dt * dt, rate + a * dt, a
    a = math.copysign(accel, d) if d else 0.0
    angle += rate * need + 0.5 * a * need * need
    return angle + rate_cmd * (dt - need), rate_cmd, 0.0


class Axis:
    """One table axis: mode, rate slewing at a set acceleration, integrated angle."""

    def __init__(self, clock: peerlib.Clock, stop_decel: float,
                 state: peerlib.StateFile | None = None) -> None:
        self.state = state
        self.clock = clock
        self.stop_decel = stop_decel
        self.t = clock.now()
        self.angle = 0.0  # degrees, unwrapped
        self.rate = 0.0  # deg/s
        self.rate_cmd = 0.0
        self.accel = stop_decel  # deg/s2 used to reach rate_cmd
        self.accel_now = 0.0
        self.mode = "OFF"
        self.pos_target: float | None = None

    def update(self) -> None:
        now = self.clock.now()
        dt = now - self.t
        self.t = now
        if dt <= 0:
            return
        if self.pos_target is not None:
            # Position move at |rate_cmd|, no acceleration phase (enough for a peer).
            d = self.pos_target - self.angle
            step = min(abs(d), abs(self.rate_cmd) * dt)
            self.angle += math.copysign(step, d)
            self.rate = math.copysign(abs(self.rate_cmd), d) if step < abs(d) else 0.0
            self.accel_now = 0.0
            self.publish()
            return
        self.angle, self.rate, self.accel_now = advance(
            self.angle, self.rate, self.rate_cmd, self.accel, dt)
        self.publish()

    def publish(self) -> None:
        """The state for coupled peers (gyro.py --table-state): enough to carry the motion on
        from `mono` exactly (`advance`) until the next command."""
        if self.state is not None:
            self.state.write(self.clock.mono(self.t), t=self.t, angle_deg=self.angle,
                             rate_deg_s=self.rate, rate_cmd_deg_s=self.rate_cmd,
                             accel_deg_s2=self.accel, moving_to=self.pos_target,
                             mode=self.mode)

    def command_rate(self, rate: float, accel: float) -> None:
        self.update()
        self.pos_target = None
        self.rate_cmd = rate
        self.accel = accel
        self.publish()

    def stop(self) -> None:
        self.command_rate(0.0, self.stop_decel)

    def wrapped(self) -> float:
        return self.angle % 360.0


def fmt(v: float) -> str:
    return f"{v:.6f}"


class Actidyn:
    """Actidyn controller state and command interpreter (one axis, number 1)."""

    MODES = {"1", "OFF", "POS", "RAT", "SIN", "STP"}

    def __init__(self, axis: Axis, log: peerlib.Log, watchdog_s: float, echo: str,
                 trip_after_rat: float | None = None) -> None:
        self.axis = axis
        self.log = log
        self.watchdog_s = watchdog_s
        self.echo = echo
        self.remote = False
        self.alarm = False
        self.last_alc = axis.clock.now()
        # --drive-trip-after-rat: the drive alarm (an amplifier fault, say) comes this long
        # after the first rate command that moves the table; once.
        self.trip_after_rat = trip_after_rat
        self.first_rat: float | None = None
        self.tripped = False

    def drop_drive(self, event: str, detail: str) -> None:
        """The drive switches off with an alarm: the axis stops, the mode reads OFF, and mode
        and motion commands are refused until ALC 0."""
        self.axis.update()
        self.axis.stop()
        self.axis.mode = "OFF"
        self.alarm = True
        self.axis.publish()
        self.log.write(event=event, detail=detail)

    def check_watchdog(self) -> None:
        now = self.axis.clock.now()
        if self.axis.mode != "OFF" and not self.alarm and now - self.last_alc > self.watchdog_s:
            self.drop_drive("watchdog", f"no ALC for {self.watchdog_s} s: drive off")
        due = self.first_rat is not None and self.trip_after_rat is not None \
            and now >= self.first_rat + self.trip_after_rat
        if due and not self.tripped and self.axis.mode != "OFF":
            self.tripped = True
            self.drop_drive("drive_trip", f"drive alarm {self.trip_after_rat} s after the "
                            "first rate command: drive off")

    async def watchdog_task(self) -> None:
        while True:
            self.check_watchdog()
            await asyncio.sleep(min(0.01, self.axis.clock.wall(0.1)))

    def element(self, cmd: str, mne: str, args: list[str], values: list[str]) -> str:
        echo = cmd.strip() if self.echo == "full" else f"{mne} {args[0].strip()}"
        return ",".join([echo, str(len(values)), *values])

    def refuse(self, mne: str, args: list[str], code: int, text: str) -> str:
        return f"{mne} {args[0].strip() if args else '?'},ERR,{code},{text}"

    def one(self, cmd: str) -> str:
        body = cmd.strip()
        mne, _, rest = body.partition(" ")
        mne = mne.upper()
        args = [a.strip() for a in rest.split(",")] if rest.strip() else []
        if not args:
            return self.refuse(mne, args, 1, "no axis")
        ax = args[0]
        if mne in ("RMT", "LOC", "ALC"):
            if args != ["0"]:
                return self.refuse(mne, args, 1, "expected argument 0")
            if mne == "RMT":
                self.remote = True
            elif mne == "LOC":
                self.remote = False
            else:
                self.alarm = False
                self.last_alc = self.axis.clock.now()
            return self.element(cmd, mne, args, [])
        if ax not in ("1", "&"):
            return self.refuse(mne, args, 2, f"no axis {ax}")
        query = len(args) == 2 and args[1] == "?"
        self.axis.update()
        if mne == "PRV" and query:
            a = self.axis
            return self.element(cmd, mne, args, [fmt(a.wrapped()), fmt(a.rate), fmt(a.accel_now)])
        if mne == "POS" and query:
            return self.element(cmd, mne, args, [fmt(self.axis.wrapped())])
        if mne == "MOD" and query:
            return self.element(cmd, mne, args, [self.axis.mode])
        if not self.remote:
            return self.refuse(mne, args, 3, "local control (send RMT 0)")
        if mne == "MOD" and len(args) == 2 and args[1].upper() in self.MODES:
            mode = args[1].upper()
            if self.alarm and mode not in ("OFF", "STP"):
                return self.refuse(mne, args, 4, "drive alarm (send ALC 0)")
            if mode in ("OFF", "STP", "1"):
                self.axis.stop()
                if mode == "STP" and self.axis.mode == "OFF":
                    mode = "OFF"
            self.axis.mode = mode
            return self.element(cmd, mne, args, [])
        if mne == "RAT" and len(args) == 3:
            try:
                rate, accel = float(args[1]), float(args[2])
            except ValueError:
                return self.refuse(mne, args, 1, "bad number")
            if self.axis.mode != "RAT":
                return self.refuse(mne, args, 5, "not in rate mode")
            if not accel > 0:
                return self.refuse(mne, args, 6, "acceleration must be positive")
            self.axis.command_rate(rate, accel)
            if rate != 0 and self.first_rat is None:
                self.first_rat = self.axis.clock.now()
            return self.element(cmd, mne, args, [])
        if mne == "POS" and len(args) == 3:
            try:
                pos, rate = float(args[1]), float(args[2])
            except ValueError:
                return self.refuse(mne, args, 1, "bad number")
            if self.axis.mode != "POS":
                return self.refuse(mne, args, 5, "not in position mode")
            self.axis.update()
            self.axis.pos_target = pos
            self.axis.rate_cmd = rate
            return self.element(cmd, mne, args, [])
        return self.refuse(mne, args, 1, "unknown command")

    def handle(self, line: str) -> str | None:
        self.check_watchdog()
        if not line.strip():
            return None
        reply = ":".join(self.one(c) for c in line.split(":")) + "\n"
        self.log.write(rx=line, tx=reply.rstrip("\n"))
        return reply


class Acutrol:
    """ACUTROL controller state and command interpreter (one axis, number 1)."""

    LONG = {
        ("utility", "lockout"): "lockout",
        ("interlock", "open"): "il_open",
        ("interlock", "reset"): "il_reset",
        ("interlock", "close"): "il_close",
        ("mode", "off"): "mode_off",
        ("mode", "rate"): "mode_rate",
        ("mode", "position"): "mode_pos",
        ("demand", "rate"): "dem_rate",
        ("demand", "position"): "dem_pos",
        ("read", "rate"): "read_rate",
        ("read", "position"): "read_pos",
    }
    # Only the short forms the public facts show.
    SHORT = {
        ("m", "r"): "mode_rate",
        ("d", "r"): "dem_rate",
        ("r", "r"): "read_rate",
        ("r", "p"): "read_pos",
    }
    LINE = re.compile(r"^:([A-Za-z]+):([A-Za-z]+)(?:\s+(.*))?$")
    NUMBER = re.compile(r"^-?\d+(\.\d+)?$")

    def __init__(self, axis: Axis, log: peerlib.Log, accel: float) -> None:
        self.axis = axis
        self.log = log
        self.accel = accel
        self.lockout = False
        self.interlock_closed = False
        self.alarm = False

    def one(self, line: str) -> str:
        m = self.LINE.match(line.strip())
        if not m:
            return "ERR syntax"
        key = (m.group(1).lower(), m.group(2).lower())
        op = self.LONG.get(key) or self.SHORT.get(key)
        if op is None:
            return f"ERR unknown command {line.strip()}"
        args = [a.strip() for a in (m.group(3) or "").split(",")] if m.group(3) else []
        self.axis.update()
        if op == "lockout":
            if args not in (["on"], ["off"], ["ON"], ["OFF"]):
                return "ERR lockout needs on or off"
            self.lockout = args[0].lower() == "on"
            return "OK"
        if not args or args[0] != "1":
            return "ERR axis out of range"
        if op == "read_rate":
            return fmt(self.axis.rate)
        if op == "read_pos":
            return fmt(self.axis.wrapped())
        if not self.lockout:
            return "ERR not in remote (lockout off)"
        if op == "il_open":
            self.interlock_closed = False
            self.axis.stop()
            self.axis.mode = "OFF"
            return "OK"
        if op == "il_reset":
            self.alarm = False
            return "OK"
        if op == "il_close":
            self.interlock_closed = True
            return "OK"
        if op == "mode_off":
            self.axis.stop()
            self.axis.mode = "OFF"
            return "OK"
        if op in ("mode_rate", "mode_pos"):
            if not self.interlock_closed:
                return "ERR interlock open"
            self.axis.mode = "RAT" if op == "mode_rate" else "POS"
            return "OK"
        if op in ("dem_rate", "dem_pos"):
            if len(args) != 2 or not self.NUMBER.match(args[1]):
                return "ERR bad demand value"
            v = float(args[1])
            if op == "dem_rate":
                if self.axis.mode != "RAT":
                    return "ERR not in rate mode"
                self.axis.command_rate(v, self.accel)
            else:
                if self.axis.mode != "POS":
                    return "ERR not in position mode"
                self.axis.pos_target = v
                self.axis.rate_cmd = 10.0
            return "OK"
        return "ERR unsupported"

    def handle(self, line: str) -> str | None:
        if not line.strip():
            return None
        reply = self.one(line)
        self.log.write(rx=line, tx=reply)
        return reply + "\r\n"


async def publish_task(axis: Axis) -> None:
    """Keep the published state fresh between requests (every 20 ms of wall time)."""
    while True:
        axis.update()
        await asyncio.sleep(0.02)


async def main() -> None:
    p = peerlib.base_args(__doc__.splitlines()[0])
    p.add_argument("--dialect", choices=["actidyn", "acutrol"], required=True)
    p.add_argument("--transport", choices=["tcp", "pty"], default="tcp")
    p.add_argument("--watchdog-s", type=float, default=30.0,
                   help="Actidyn: drive off without ALC for this long, bench s (default 30)")
    p.add_argument("--echo", choices=["short", "full"], default="short")
    p.add_argument("--drive-trip-after-rat", type=float, metavar="S",
                   help="Actidyn: drop the drive with an alarm S bench seconds after the first "
                        "rate command that moves the table (once)")
    p.add_argument("--state", help="publish the axis state here for coupled peers "
                                   "(gyro.py --table-state)")
    p.add_argument("--stop-decel", type=float, default=10.0, help="deg/s2 (default 10)")
    p.add_argument("--acutrol-accel", type=float, default=10.0, help="deg/s2 (default 10)")
    args = p.parse_args()
    clock = peerlib.Clock(args.time_scale)
    log = peerlib.Log(args.log, clock)
    axis = Axis(clock, args.stop_decel, peerlib.StateFile(args.state) if args.state else None)
    axis.publish()
    tasks = []
    if args.state:
        tasks.append(asyncio.create_task(publish_task(axis)))
    if args.dialect == "actidyn":
        ctl = Actidyn(axis, log, args.watchdog_s, args.echo, args.drive_trip_after_rat)
        server = peerlib.LineServer(ctl.handle, b"\n")
        tasks.append(asyncio.create_task(ctl.watchdog_task()))
    else:
        if args.transport != "tcp":
            p.error("the ACUTROL peer serves TCP only")
        ctl = Acutrol(axis, log, args.acutrol_accel)
        server = peerlib.LineServer(ctl.handle, b"\n")
    name = f"table-{args.dialect}"
    if args.transport == "tcp":
        srv = await server.serve_tcp(name)
        await peerlib.run_until_stdin_closes(*tasks)
        srv.close()
    else:
        tasks.append(asyncio.create_task(server.serve_pty(name)))
        await peerlib.run_until_stdin_closes(*tasks)


if __name__ == "__main__":
    asyncio.run(main())
