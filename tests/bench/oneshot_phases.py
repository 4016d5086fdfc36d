#!/usr/bin/env python3
"""Phases of the one-shot figure from an ftrace text dump
(tests/bench/oneshot-timeline): per run of the baseline (bench_vcan_mailbox
--raw-once) and of `cogwctl sdo read`, the time between system calls that
bound each phase; medians over the runs, in microseconds. Also the daemon's
line thread (cogw-bench0): REGISTER received to its answer sent, request
received to the SDO frame written. docs/fastpath.md "One-shot `cogwctl`"."""
import re
import statistics
import sys

LINE = re.compile(r'^\s*(.+?)-(\d+)\s+\[\d+\]\s+\S+\s+([\d.]+): ([A-Za-z0-9_]+):? ?(.*)$')
REGISTER_LEN = '0xbc'  # the size of a REGISTER message
LINE_THREAD = 'cogw-bench0'


def load(path):
    events = []
    with open(path) as f:
        for text in f:
            m = LINE.match(text)
            if m:
                comm, pid, ts, name, rest = m.groups()
                events.append((float(ts), comm, int(pid), name, rest))
    return events


def calls_of(events, pid, start):
    """(enter, name, exit) of every system call of pid after start."""
    calls, open_calls = [], {}
    for ts, _, p, name, rest in events:
        if p != pid or ts < start or not name.startswith('sys_'):
            continue
        if rest.startswith('->'):
            if name in open_calls:
                calls.append((open_calls.pop(name), name[4:], ts))
        else:
            open_calls[name] = ts
    calls.extend((t, n[4:], t) for n, t in open_calls.items())
    return sorted(calls)


def phases(events, kind, pid):
    t_exec = next(e[0] for e in events if e[3] == 'sched_process_exec' and e[2] == pid)
    calls = calls_of(events, pid, t_exec)
    gone = [e[0] for e in events if e[3] == 'sched_switch' and
            ('prev_pid=%d ' % pid) in e[4] and 'prev_state=Z' in e[4]]
    ld_start = calls[1][0] if calls[0][1] == 'execve' else calls[0][0]
    ld_end_i = max(i for i, c in enumerate(calls) if c[1] == 'munmap' and i < 40)
    ld_end = calls[ld_end_i][2]
    main = calls[ld_end_i + 1:]
    sends = [c for c in main if c[1] == 'mq_timedsend']
    recvs = [c for c in main if c[1] == 'mq_timedreceive']
    exit_group = next(c[0] for c in main if c[1] == 'exit_group')
    if kind == 'ctl':
        second_send, second_answer = sends[1][0], recvs[1][2]
    else:
        second_send = next(c for c in main if c[1] == 'write')[0]
        second_answer = next(c for c in main if c[1] == 'read')[2]
    marks = [
        ('exec to the loader\'s first call', t_exec, ld_start),
        ('the loader', ld_start, ld_end),
        ('libc start, main to its first call', ld_end, main[0][0]),
        ('... to the first message sent', main[0][0], sends[0][0]),
        ('first round trip (mq / REGISTER)', sends[0][0], recvs[0][2]),
        ('answer to the second exchange', recvs[0][2], second_send),
        ('second exchange (CAN / SDO request)', second_send, second_answer),
        ('answer to exit_group', second_answer, exit_group),
        ('exit_group until gone', exit_group, gone[0] if gone else exit_group),
        ('exec to gone', t_exec, gone[0] if gone else exit_group),
    ]
    return [(name, (b - a) * 1e6) for name, a, b in marks]


def line_thread(events):
    reg, req, t_reg, t_req = [], [], None, None
    for ts, comm, _, name, rest in events:
        if comm != LINE_THREAD:
            continue
        if name == 'sys_mq_timedreceive' and rest.startswith('-> ' + REGISTER_LEN):
            t_reg = ts
        elif name == 'sys_mq_timedsend' and t_reg is not None:
            reg.append((ts - t_reg) * 1e6)
            t_reg = None
        elif name == 'sys_mq_timedreceive' and rest.startswith('-> 0x40'):
            t_req = ts
        elif name == 'sys_write' and t_req is not None:
            req.append((ts - t_req) * 1e6)
            t_req = None
    return reg, req


def main():
    events = load(sys.argv[1])
    marks = [(i, e) for i, e in enumerate(events) if e[3] == 'tracing_mark_write']
    table = {}
    for k in range(len(marks) - 1):
        i0, mark = marks[k]
        i1 = marks[k + 1][0]
        kind = mark[4].split()[1]
        execs = [e for e in events[i0:i1] if e[3] == 'sched_process_exec']
        if kind not in ('base', 'ctl') or not execs:
            continue
        try:
            rows = phases(events[i0:i1 + 400], kind, execs[0][2])
        except (StopIteration, IndexError, ValueError):
            print('run "%s": incomplete in the trace, left out' % mark[4])
            continue
        for name, us in rows:
            table.setdefault(name, {}).setdefault(kind, []).append(us)
    print('%-40s %10s %10s' % ('phase (median us)', 'baseline', 'cogwctl'))
    for name, by_kind in table.items():
        print('%-40s %10.0f %10.0f' % (name, statistics.median(by_kind.get('base', [0])),
                                        statistics.median(by_kind.get('ctl', [0]))))
    reg, req = line_thread(events)
    if reg:
        print('line thread: REGISTER received to answer sent: median %.0f us (%d)' %
              (statistics.median(reg), len(reg)))
    if req:
        print('line thread: request received to SDO frame written: median %.0f us (%d)' %
              (statistics.median(req), len(req)))


if __name__ == '__main__':
    main()
