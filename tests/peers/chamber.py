"""Independent peers of the chamber controllers: Watlow F4, Watlow F4T and Eurotherm 3216 as
pymodbus servers, over Modbus TCP (loopback, OS-chosen port) or Modbus RTU on a pseudo-terminal.

Written from the public register facts only (docs/protocols/peers.md quotes them), not from
bench's register maps:

Watlow F4 (int16, implied decimals from register 606): model 0 = 5270, PV input 1 = 100, power
103/107 (percent x 100, the peer's choice), profile status 200, static set point loop 1 = 300,
set point limits 602 (low) / 603 (high), decimal places 606, units 901 (1 = deg C, 0 = deg F),
current ramping set point 4122.
Watlow F4T loop 1 (IEEE float32 over two registers, LOW WORD FIRST): loop mode 2730 (10 auto),
set point min/max 2774/2776, set point 2782, power 2784/2808 (percent), working set point 2810,
process value 2820.
Eurotherm 3216 (int16 scaled by the display decimals, --decimals): PV.IN 1, target SP 2 (the
selected set point), working SP 5 (read-only), SP select 15 (0 SP1, 1 SP2), SP1/SP2 24/25,
remote comms SP 26 (in use when 276 = 1), set point rate limit 35 (per minute, 0 = off).
Registers 2, 24 and 25 live in EEPROM (~100 k writes): the peer counts those writes.

Physics (bench time): the working set point follows the active set point (Eurotherm: at the rate
limit); the air follows the working set point with a first-order lag (--tau-s). Writes outside
the set point limits are refused with exception 3 (illegal data value); writes to read-only or
unknown registers with exception 2 (illegal data address).

Every request is logged: {"fc", "addr", "count"} for reads with the "words" returned, {"fc",
"addr", "words"} for writes, and "exception" when refused.

Coupling: --state FILE publishes the air temperature (peerlib.StateFile) for gyro.py
--chamber-state.

Faults: --status-register ADDR serves a status word there (the peer's own choice: the public
facts give no alarm or door register for these controllers): bit 0 alarm, from --alarm-after S
bench seconds on; bit 1 door open, from --door-open-after S on.
"""

from __future__ import annotations

import asyncio
import math
import os
import struct
import sys
import types

import peerlib
import serial
import serial.serialposix
from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

ILLEGAL_ADDRESS = ExcCodes.ILLEGAL_ADDRESS
ILLEGAL_VALUE = ExcCodes.ILLEGAL_VALUE


def i16(v: int) -> int:
    return v - 0x10000 if v & 0x8000 else v


def u16(v: int) -> int:
    return v & 0xFFFF


class Chamber:
    """Air temperature lagging the working set point; the working set point follows the active
    set point at `rate_c_per_min` (0 = at once)."""

    def __init__(self, clock: peerlib.Clock, air_c: float, tau_s: float,
                 state: peerlib.StateFile | None = None) -> None:
        self.state = state
        self.clock = clock
        self.t = clock.now()
        self.air = air_c
        self.wsp = air_c
        self.sp = air_c
        self.rate_c_per_min = 0.0
        self.tau = tau_s

    def update(self) -> None:
        now = self.clock.now()
        dt = now - self.t
        self.t = now
        while dt > 0:
            h = min(dt, 0.5)
            dt -= h
            if self.rate_c_per_min > 0:
                step = self.rate_c_per_min / 60.0 * h
                d = self.sp - self.wsp
                self.wsp += math.copysign(min(step, abs(d)), d)
            else:
                self.wsp = self.sp
            self.air += (self.wsp - self.air) * (1.0 - math.exp(-h / self.tau))
        if self.state is not None:
            self.state.write(self.clock.mono(now), t=now, air_c=self.air, wsp_c=self.wsp,
                             sp_c=self.sp)

    def power_percent(self) -> float:
        return max(-100.0, min(100.0, (self.wsp - self.air) * 20.0))


class Model:
    """A register file: `read(addr)` / `write(addr, word)` per register, with exceptions."""

    name = "?"
    registers: tuple[int, ...] = ()

    def __init__(self, chamber: Chamber, args) -> None:
        self.ch = chamber
        self.args = args
        self.eeprom_writes: dict[int, int] = {}

    def read(self, addr: int) -> int | ExcCodes:
        raise NotImplementedError

    def write(self, addr: int, words: list[int]) -> ExcCodes | None:
        raise NotImplementedError


class WatlowF4(Model):
    name = "watlow_f4"
    registers = (0, 100, 103, 107, 200, 300, 602, 603, 606, 901, 4122)

    def __init__(self, chamber, args):
        super().__init__(chamber, args)
        self.decimals = 1
        self.fahrenheit = args.fahrenheit
        self.sp_low, self.sp_high = args.sp_limits

    def to_display(self, c: float) -> float:
        return c * 9 / 5 + 32 if self.fahrenheit else c

    def from_display(self, v: float) -> float:
        return (v - 32) * 5 / 9 if self.fahrenheit else v

    def enc(self, c: float) -> int:
        return u16(round(self.to_display(c) * 10**self.decimals))

    def dec(self, w: int) -> float:
        return self.from_display(i16(w) / 10**self.decimals)

    def read(self, addr):
        ch = self.ch
        return {
            0: 5270,
            100: self.enc(ch.air),
            103: u16(round(ch.power_percent() * 100)),
            107: 0,
            200: 0,
            300: self.enc(ch.sp),
            602: self.enc(self.sp_low),
            603: self.enc(self.sp_high),
            606: self.decimals,
            901: 0 if self.fahrenheit else 1,
            4122: self.enc(ch.wsp),
        }.get(addr, ILLEGAL_ADDRESS)

    def write(self, addr, words):
        if addr != 300 or len(words) != 1:
            return ILLEGAL_ADDRESS
        c = self.dec(words[0])
        if not self.sp_low - 1e-9 <= c <= self.sp_high + 1e-9:
            return ILLEGAL_VALUE
        self.ch.sp = c
        return None


class WatlowF4T(Model):
    name = "watlow_f4t"
    FLOATS = (2774, 2776, 2782, 2784, 2808, 2810, 2820)
    registers = (2730,) + tuple(a + i for a in FLOATS for i in (0, 1))

    def __init__(self, chamber, args):
        super().__init__(chamber, args)
        self.sp_min, self.sp_max = args.sp_limits
        self.pending: dict[int, int] = {}

    @staticmethod
    def words(v: float) -> tuple[int, int]:
        hi, lo = struct.unpack(">HH", struct.pack(">f", v))
        return lo, hi  # low word first

    @staticmethod
    def value(lo: int, hi: int) -> float:
        return struct.unpack(">f", struct.pack(">HH", hi, lo))[0]

    def floats(self) -> dict[int, float]:
        ch = self.ch
        return {
            2774: self.sp_min,
            2776: self.sp_max,
            2782: ch.sp,
            2784: ch.power_percent(),
            2808: ch.power_percent(),
            2810: ch.wsp,
            2820: ch.air,
        }

    def read(self, addr):
        if addr == 2730:
            return 10  # auto
        base = addr - (addr - 2774) % 2 if addr >= 2774 else addr
        f = self.floats()
        if base not in f:
            return ILLEGAL_ADDRESS
        lo, hi = self.words(f[base])
        return lo if addr == base else hi

    def write(self, addr, words):
        # Only a whole float written in one request (fc 16, two words) sets the set point.
        if addr != 2782 or len(words) != 2:
            return ILLEGAL_ADDRESS
        v = self.value(words[0], words[1])
        if not (math.isfinite(v) and self.sp_min <= v <= self.sp_max):
            return ILLEGAL_VALUE
        self.ch.sp = v
        return None


class Eurotherm3216(Model):
    name = "eurotherm_3216"
    registers = (1, 2, 5, 15, 24, 25, 26, 35, 276)
    EEPROM = (2, 24, 25)

    def __init__(self, chamber, args):
        super().__init__(chamber, args)
        self.decimals = args.decimals
        self.sp_select = 0
        self.sp1 = chamber.sp
        self.sp2 = chamber.sp
        self.remote_sp = chamber.sp
        self.remote_enabled = 0
        self.rate_word = 0
        self.sp_low, self.sp_high = args.sp_limits

    def enc(self, c: float) -> int:
        return u16(round(c * 10**self.decimals))

    def dec(self, w: int) -> float:
        return i16(w) / 10**self.decimals

    def active(self) -> float:
        if self.remote_enabled:
            return self.remote_sp
        return self.sp2 if self.sp_select else self.sp1

    def apply(self) -> None:
        self.ch.sp = self.active()
        self.ch.rate_c_per_min = max(0.0, self.dec(self.rate_word))

    def read(self, addr):
        return {
            1: self.enc(self.ch.air),
            2: self.enc(self.active()),
            5: self.enc(self.ch.wsp),
            15: self.sp_select,
            24: self.enc(self.sp1),
            25: self.enc(self.sp2),
            26: self.enc(self.remote_sp),
            35: self.rate_word,
            276: self.remote_enabled,
        }.get(addr, ILLEGAL_ADDRESS)

    def write(self, addr, words):
        if len(words) != 1 or addr not in (2, 15, 24, 25, 26, 35, 276):
            return ILLEGAL_ADDRESS
        w = words[0]
        if addr in (2, 24, 25, 26) and not self.sp_low <= self.dec(w) <= self.sp_high:
            return ILLEGAL_VALUE
        if addr in self.EEPROM:
            self.eeprom_writes[addr] = self.eeprom_writes.get(addr, 0) + 1
        if addr == 2:
            # The target set point is the selected one (stored in EEPROM).
            if self.remote_enabled:
                self.remote_sp = self.dec(w)
            elif self.sp_select:
                self.sp2 = self.dec(w)
            else:
                self.sp1 = self.dec(w)
        elif addr == 15:
            if w not in (0, 1):
                return ILLEGAL_VALUE
            self.sp_select = w
        elif addr == 24:
            self.sp1 = self.dec(w)
        elif addr == 25:
            self.sp2 = self.dec(w)
        elif addr == 26:
            self.remote_sp = self.dec(w)
        elif addr == 35:
            if i16(w) < 0:
                return ILLEGAL_VALUE
            self.rate_word = w
        elif addr == 276:
            if w not in (0, 1):
                return ILLEGAL_VALUE
            self.remote_enabled = w
        self.apply()
        return None


MODELS = {m.name: m for m in (WatlowF4, WatlowF4T, Eurotherm3216)}


def fd_serial_handler(master_fd: int) -> str:
    """Register a pyserial URL handler "peerfd://" that serves on an already open pty master
    (pymodbus opens its serial port through serial.serial_for_url). Returns the URL."""

    class FdSerial(serial.serialposix.Serial):
        def open(self):
            self.fd = os.dup(master_fd)
            os.set_blocking(self.fd, False)
            self.pipe_abort_read_r, self.pipe_abort_read_w = os.pipe()
            self.pipe_abort_write_r, self.pipe_abort_write_w = os.pipe()
            os.set_blocking(self.pipe_abort_read_r, False)
            os.set_blocking(self.pipe_abort_write_r, False)
            self.is_open = True

        def _reconfigure_port(self, force_update=False):
            pass  # a pty master has no line settings of its own

    package = types.ModuleType("peer_url_handlers")
    package.__path__ = []
    module = types.ModuleType("peer_url_handlers.protocol_peerfd")
    module.Serial = FdSerial
    sys.modules["peer_url_handlers"] = package
    sys.modules["peer_url_handlers.protocol_peerfd"] = module
    if "peer_url_handlers" not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append("peer_url_handlers")
    return f"peerfd://{master_fd}"


async def publish_task(chamber: Chamber) -> None:
    """Keep the published air temperature fresh between requests (every 0.1 s of wall time)."""
    while True:
        chamber.update()
        await asyncio.sleep(0.1)


async def main() -> None:
    p = peerlib.base_args(__doc__.splitlines()[0])
    p.add_argument("--model", choices=sorted(MODELS), required=True)
    p.add_argument("--transport", choices=["tcp", "rtu"], default="tcp")
    p.add_argument("--unit", type=int, default=1, help="Modbus unit id (default 1)")
    p.add_argument("--air-c", type=float, default=23.0, help="initial air and set point")
    p.add_argument("--tau-s", type=float, default=20.0, help="air lag time constant, bench s")
    p.add_argument("--decimals", type=int, default=1, help="Eurotherm display decimals")
    p.add_argument("--fahrenheit", action="store_true", help="Watlow F4 set to deg F (901 = 0)")
    p.add_argument("--status-register", type=int, metavar="ADDR",
                   help="serve a status word here: bit 0 alarm, bit 1 door open")
    p.add_argument("--alarm-after", type=float, metavar="S", help="alarm bit from S bench s on")
    p.add_argument("--door-open-after", type=float, metavar="S",
                   help="door bit from S bench s on")
    p.add_argument("--state", help="publish the air temperature here for coupled peers "
                                   "(gyro.py --chamber-state)")
    p.add_argument("--sp-limits", type=float, nargs=2, default=(-70.0, 190.0),
                   metavar=("LOW", "HIGH"), help="set point limits, deg C")
    args = p.parse_args()
    clock = peerlib.Clock(args.time_scale)
    log = peerlib.Log(args.log, clock)
    chamber = Chamber(clock, args.air_c, args.tau_s,
                      peerlib.StateFile(args.state) if args.state else None)
    model: Model = MODELS[args.model](chamber, args)
    if isinstance(model, Eurotherm3216):
        model.apply()
    registers = model.registers
    if args.status_register is not None:
        registers += (args.status_register,)
        read_model = model.read

        def read(addr):
            if addr != args.status_register:
                return read_model(addr)
            now = clock.now()
            after = lambda s: s is not None and now >= s  # noqa: E731
            return (1 if after(args.alarm_after) else 0) | (2 if after(args.door_open_after) else 0)

        model.read = read
    lo, hi = min(registers), max(registers)

    async def action(fc, start, address, count, registers, set_values):
        chamber.update()
        entry = {"fc": fc, "addr": address, "unit": args.unit}
        if set_values is None and fc not in (3, 4):
            # pymodbus reads back after a write to build the response: not a request.
            for a in range(address, address + count):
                w = model.read(a)
                registers[a - start] = 0 if isinstance(w, ExcCodes) else w
            return None
        if set_values is None:
            entry["count"] = count
            words = []
            for a in range(address, address + count):
                w = model.read(a)
                if isinstance(w, ExcCodes):
                    log.write(**entry, exception=int(w))
                    return w
                words.append(w)
            registers[address - start : address - start + count] = words
            log.write(**entry, words=words)
            return None
        words = [int(v) for v in set_values]
        result = model.write(address, words)
        if result is not None:
            log.write(**entry, words=words, exception=int(result))
            return result
        log.write(**entry, words=words)
        return None

    device = SimDevice(
        id=args.unit,
        simdata=[SimData(address=lo, count=hi - lo + 1, values=0, datatype=DataType.REGISTERS)],
        action=action,
    )
    name = f"chamber-{args.model}"
    if args.transport == "tcp":
        server = ModbusTcpServer(device, address=("127.0.0.1", 0))
        await server.serve_forever(background=True)
        sock = server.transport.sockets[0] if hasattr(server.transport, "sockets") else None
        host, port = sock.getsockname()[:2]
        peerlib.ready(name, tcp=f"{host}:{port}")
    else:
        pty = peerlib.Pty()
        server = ModbusSerialServer(device, port=fd_serial_handler(pty.master), baudrate=9600)
        await server.serve_forever(background=True)
        peerlib.ready(name, pty=pty.path)
    tasks = [asyncio.create_task(publish_task(chamber))] if args.state else []
    await peerlib.run_until_stdin_closes(*tasks)
    log.write(event="exit", eeprom_writes={str(k): v for k, v in model.eeprom_writes.items()})
    await server.shutdown()


if __name__ == "__main__":
    asyncio.run(main())
