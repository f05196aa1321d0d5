#!/usr/bin/env python3
"""An Oriental AZ drive in direct-data operation, on pymodbus: an independent peer for
gelrig's Modbus driver.

gelrig's own twin (rig/src/twins/modbus/) shares the driver's reading of the manual; this
drive is written separately, from the manual's description of the direct-data operation,
on an independent Modbus implementation (pymodbus), so a misreading shared by driver and
twin shows up here.

Registers (all 32-bit objects are two registers, upper word first unless --low-first):
  0x0058 data number, 0x005A operation type (1 absolute, 2 incremental), 0x005C position,
  0x005E speed, 0x0060 acceleration, 0x0062 deceleration, 0x0064 current,
  0x0066 trigger (1: start with all the data; the drive clears it to 0);
  0x007D input command (bit 4 ZHOME, bit 5 STOP, bit 7 ALM-RST);
  0x007F output status (bit 4 HOME-END, bit 7 ALM, bit 8 BUSY, bit 14 IN-POS);
  0x0120 feedback position (32-bit).
Anything else answers Illegal Data Address; functions other than FC3, FC6 and FC16
answer Illegal Function.

Usage: az_drive.py (--tcp | --serial PATH [--parity E|O|N]) [--unit 1] [--busy-latency-ms N]
       [--overshoot-steps N] [--busy-once] [--ignore-trigger] [--limits LO HI]
With --tcp it listens on 127.0.0.1 on a free port and prints `LISTEN host:port`.
"""

import argparse
import asyncio
import socket
import sys
import threading
import time

from pymodbus.constants import ExcCodes
from pymodbus.datastore import ModbusServerContext
from pymodbus.datastore.context import ModbusBaseDeviceContext
from pymodbus.server import StartAsyncSerialServer, StartAsyncTcpServer

BLOCK = range(0x0058, 0x0068)
INPUT, STATUS, FEEDBACK = 0x007D, 0x007F, 0x0120
ZHOME, STOP, ALM_RST = 1 << 4, 1 << 5, 1 << 7
HOME_END, ALM, BUSY, IN_POS = 1 << 4, 1 << 7, 1 << 8, 1 << 14
SETTLE_S = 0.005  # IN-POS comes on this long after the motion ends


def s32(v):
    v &= 0xFFFFFFFF
    return v - (1 << 32) if v & 0x80000000 else v


class Az(ModbusBaseDeviceContext):
    def __init__(self, opts):
        self.o = opts
        self.lock = threading.Lock()
        self.regs = {a: 0 for a in BLOCK}
        self.regs[INPUT] = 0
        self.pos = 1234.0  # steps, unknown until homed
        self.homed = False
        self.alarm = False
        self.move = None  # (from, to, t0, speed_steps_s)
        self.busy_once = opts.busy_once

    # -- words
    def get32(self, a):
        hi, lo = self.regs[a], self.regs[a + 1]
        if self.o.low_first:
            hi, lo = lo, hi
        return s32((hi << 16) | lo)

    def split32(self, v):
        v &= 0xFFFFFFFF
        hi, lo = v >> 16, v & 0xFFFF
        return [lo, hi] if self.o.low_first else [hi, lo]

    # -- motion: a latency before BUSY, constant speed, an overshoot, then IN-POS
    def state(self, now):
        if self.move is None:
            return self.pos, False, True
        frm, to, t0, v, latency = self.move
        t = now - t0
        if t < latency:
            return frm, False, False
        end = to + self.o.overshoot_steps * (1 if to >= frm else -1) if to != frm else to
        dist = abs(end - frm)
        done_at = dist / v
        if t - latency < done_at:
            step = v * (t - latency)
            return frm + (step if end >= frm else -step), True, False
        self.pos = end
        settled = t - latency - done_at >= SETTLE_S
        if settled:
            self.move = None
            if self.homing:
                self.homed = True
                self.homing = False
        return end, False, settled

    def start(self, to, speed, latency):
        now = time.monotonic()
        pos, _, _ = self.state(now)
        self.pos = pos
        self.move = (pos, float(to), now, float(speed), latency)

    # -- the Modbus data model
    def validate(self, func_code, address, count=1):
        return True

    def getValues(self, func_code, address, count=1):
        # FC3 reads; FC6 and FC16 read back what they wrote for their reply.
        if func_code not in (3, 6, 16):
            return ExcCodes.ILLEGAL_FUNCTION
        with self.lock:
            pos, busy, in_pos = self.state(time.monotonic())
            out = []
            for a in range(address, address + count):
                if a == STATUS:
                    s = (BUSY if busy else 0) | (IN_POS if in_pos and not busy else 0)
                    s |= (HOME_END if self.homed else 0) | (ALM if self.alarm else 0)
                    out.append(s)
                elif a in (FEEDBACK, FEEDBACK + 1):
                    w = self.split32(int(round(pos)))
                    out.append(w[a - FEEDBACK])
                elif a in self.regs:
                    out.append(self.regs[a])
                else:
                    return ExcCodes.ILLEGAL_ADDRESS
            return out

    def setValues(self, func_code, address, values):
        if func_code not in (6, 16):
            return ExcCodes.ILLEGAL_FUNCTION
        with self.lock:
            span = range(address, address + len(values))
            if any(a not in self.regs for a in span):
                return ExcCodes.ILLEGAL_ADDRESS
            triggers = 0x0066 in span or 0x0067 in span
            if triggers and self.busy_once:
                # Still digesting: try again later, nothing applied.
                self.busy_once = False
                return ExcCodes.DEVICE_BUSY
            for a, v in zip(span, values):
                self.regs[a] = v
            now = time.monotonic()
            _, busy, _ = self.state(now)
            if triggers and self.get32(0x0066) == 1:
                self.regs[0x0066] = self.regs[0x0067] = 0
                op, target, speed = self.get32(0x005A), self.get32(0x005C), self.get32(0x005E)
                if op == 2:
                    target = int(round(self.pos)) + target
                elif op != 1:
                    return ExcCodes.ILLEGAL_VALUE
                lo, hi = self.o.limits
                if not (lo <= target <= hi) or speed <= 0:
                    self.alarm = True
                    return ExcCodes.ILLEGAL_VALUE
                if busy:
                    return ExcCodes.DEVICE_BUSY
                if not self.o.ignore_trigger:
                    self.homing = False
                    self.start(target, speed, self.o.busy_latency_ms / 1000.0)
            if INPUT in span:
                cmd = self.regs[INPUT]
                if cmd & ALM_RST:
                    self.alarm = False
                if cmd & STOP:
                    pos, _, _ = self.state(now)
                    self.pos, self.move = pos, None
                elif cmd & ZHOME:
                    self.homing = True
                    self.start(0, 20000, 0.0)
            return None

    homing = False


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument("--tcp", action="store_true")
    where.add_argument("--serial")
    p.add_argument("--unit", type=int, default=1)
    p.add_argument("--low-first", action="store_true")
    p.add_argument("--parity", default="E", choices=["E", "O", "N"])
    p.add_argument("--busy-latency-ms", type=float, default=0.0)
    p.add_argument("--overshoot-steps", type=float, default=0.0)
    p.add_argument("--busy-once", action="store_true")
    p.add_argument("--ignore-trigger", action="store_true")
    p.add_argument("--limits", type=int, nargs=2, default=[-18000, 18000])
    o = p.parse_args()
    context = ModbusServerContext(devices={o.unit: Az(o)}, single=False)
    if o.tcp:
        sock = socket.socket()
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
        sock.close()
        print(f"LISTEN 127.0.0.1:{port}", flush=True)
        asyncio.run(StartAsyncTcpServer(context, address=("127.0.0.1", port)))
    else:
        print(f"SERIAL {o.serial}", flush=True)
        asyncio.run(
            StartAsyncSerialServer(
                context, port=o.serial, framer="rtu", baudrate=19200, parity=o.parity,
                stopbits=2 if o.parity == "N" else 1, bytesize=8,
            )
        )


if __name__ == "__main__":
    sys.exit(main())
