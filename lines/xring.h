/* SPDX-License-Identifier: MIT */
/*
 * lines/xring.h - cross-line hand-off: a bounded, lock-free ring that
 * carries fixed-size messages from exactly one producer thread to exactly
 * one consumer thread, and wakes the consumer through an eventfd.
 *
 * Topology: one ring per ordered pair of lines (xring_mesh), so every ring
 * has a single producer (the line thread of `from`) and a single consumer
 * (the line thread of `to`). No lock, no allocation and no blocking call
 * after creation; two lines never share a writable cache line except
 * through the ring's own head/tail.
 *
 * Back-pressure rule (never block, never lose silently):
 * - Full ring (the target is slow or stuck): xring_push() returns -ENOBUFS
 *   at once and counts a drop. The producer answers whoever waits for that
 *   message with an error (for a routed SDO request: SDO abort 0A000003h
 *   "routing busy" or the mailbox's MBX_E_BUSY).
 * - Closed ring (the target line stopped, xring_close()): xring_push()
 *   returns -EPIPE and counts a drop; same answer.
 * - A message that is taken but never answered (the target died after
 *   popping it) is the producer's own timeout: every request sent over a
 *   ring is parked in the producer's pending table with a deadline.
 *
 * Wake-up: the producer writes the consumer's eventfd only when the ring
 * was empty before its message (the consumer drains until empty, so one
 * wake-up covers a burst). The empty test and the consumer's last look use
 * sequentially consistent fences on both sides (Dekker): either the
 * producer sees the ring empty and wakes, or the consumer sees the new
 * message; a wake-up is never lost. Spurious wake-ups are harmless. A
 * quiet push (xring_push_quiet) skips the wake-up on purpose; the next
 * ordinary push then wakes the consumer even though the ring was not empty.
 *
 * Threads: xring_push from the producer thread only, xring_pop/close from
 * the consumer thread only, xring_stats from any thread, create/destroy
 * while neither runs.
 */
#ifndef COGW_LINES_XRING_H
#define COGW_LINES_XRING_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct xring xring;

typedef struct xring_stats {
	uint64_t pushed;     /* messages accepted */
	uint64_t popped;     /* messages taken by the consumer */
	uint64_t dropped;    /* refused: full or closed */
	uint64_t wakes;      /* eventfd writes */
	uint32_t high_water; /* most messages seen queued at a push */
} xring_stats;

/* slots: a power of two, 2..65536; msg_max: largest message, 1..65536.
 * wakefd: the consumer's eventfd (not owned), or -1 for none. Returns 0,
 * -EINVAL or -ENOMEM. */
int xring_create(xring **out, uint32_t slots, uint32_t msg_max, int wakefd);
void xring_destroy(xring *r); /* accepts NULL */

/* Producer: copy one message in. Returns 0, -EMSGSIZE (len 0 or larger
 * than msg_max: not counted as a drop, a programming error), -ENOBUFS
 * (full: dropped, counted) or -EPIPE (closed: dropped, counted). */
int xring_push(xring *r, const void *msg, uint32_t len);

/* Producer: as xring_push, but the consumer is not woken for it unless
 * wake_at messages (or more) are now queued: it takes the message at its
 * next wake-up, whatever causes that (the consumer must look at its rings
 * then, not only when the eventfd fires: line_ext before_events). The next
 * xring_push wakes it even if the ring was not empty. For a message that
 * may wait until the consumer wakes for something else. */
int xring_push_quiet(xring *r, const void *msg, uint32_t len, uint32_t wake_at);

/* Producer: as xring_push, but the consumer's wake-up is owed, not done:
 * xring_wake does it. For a message that announces something the producer
 * does right after (a frame it sends for the consumer): the wake-up's
 * system call then does not delay that. */
int xring_push_wake_later(xring *r, const void *msg, uint32_t len);
/* Producer: the wake-up owed by xring_push_wake_later (or quiet pushes),
 * if any, and only if the consumer has not taken every message already. */
void xring_wake(xring *r);

/* Consumer: take the oldest message into buf (cap >= msg_max). Returns its
 * length, 0 when empty, or -EMSGSIZE if cap is too small (nothing taken). */
int xring_pop(xring *r, void *buf, uint32_t cap);

/* Consumer: refuse further messages (the line is stopping). Messages
 * already queued can still be popped. */
void xring_close(xring *r);
bool xring_is_closed(const xring *r);

/* Messages queued now (approximate while both sides run). */
uint32_t xring_count(const xring *r);
void xring_stats_get(const xring *r, xring_stats *out);

/* ---- the mesh: one ring per ordered pair of lines --------------------------- */

typedef struct xring_mesh xring_mesh;

/* n lines (2..64), every ring with `slots` messages of up to msg_max
 * bytes. wakefds[i]: the eventfd that wakes line i's consumer (not owned),
 * or wakefds NULL: the mesh creates one eventfd per line (non-blocking,
 * owned, see xring_mesh_wake_fd; give it to the line as line_ext.wake_fd).
 * Returns 0, -EINVAL, -ENOMEM, or -errno of eventfd(). */
int xring_mesh_create(xring_mesh **out, unsigned n, const int *wakefds, uint32_t slots,
		      uint32_t msg_max);
/* The eventfd that wakes line `to` (all rings into it share it). */
int xring_mesh_wake_fd(const xring_mesh *m, unsigned to);
void xring_mesh_destroy(xring_mesh *m); /* accepts NULL */
unsigned xring_mesh_lines(const xring_mesh *m);
/* The ring from line `from` to line `to`; NULL if from == to or out of
 * range. */
xring *xring_mesh_get(xring_mesh *m, unsigned from, unsigned to);

#endif /* COGW_LINES_XRING_H */
