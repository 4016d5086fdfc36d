/* SPDX-License-Identifier: MIT */
/*
 * core/time.h - TIME producer and consumer (CiA 301 §7.2.6, object 1012h)
 * and the TIME_OF_DAY encoding.
 *
 * TIME_OF_DAY (CiA 301 §7.1.6.5) is 6 bytes, little-endian:
 *     bits  0..27  milliseconds after midnight (0..86399999)
 *     bits 28..31  reserved (sent as 0, ignored on reception)
 *     bits 32..47  days since 1984-01-01 (UNSIGNED16)
 * so it covers 1984-01-01 .. 2163-06-06. No time zone is defined: the
 * project treats it as UTC.
 *
 * 1012h (COB-ID TIME, UNSIGNED32):
 *     bit 31  1 = this node consumes TIME
 *     bit 30  1 = this node produces TIME
 *     bit 29  1 = 29-bit CAN-ID
 * The CAN-ID bits (0..29) cannot change while bit 30 or bit 31 is set
 * (0x06090030), like the other "exists" COB-IDs of CiA 301. Without 1012h
 * the node neither consumes nor produces. co_od_add_comm_defaults_time()
 * creates 1012h = 100h (neither; the integrator sets bit 30 or 31).
 *
 * TIME frames are produced and consumed in PRE-OPERATIONAL and OPERATIONAL
 * only (CiA 301 §7.3.2.2, table 88). The producer has no period of its own:
 * CiA 301 leaves that to the application, which calls co_time_send() (the
 * daemon does it from its own timer; the core reads no clock).
 *
 * All functions: owning thread only; 0 or a negative errno.
 */
#ifndef COGW_CORE_TIME_H
#define COGW_CORE_TIME_H

#include <stdint.h>

#include "core/co.h"

#define CO_TIME_COB_DEFAULT 0x100u
#define CO_TIME_CONSUMER 0x80000000u /* 1012h bit 31 */
#define CO_TIME_PRODUCER 0x40000000u /* 1012h bit 30 */
#define CO_TIME_EXT CO_COB_EXT       /* 1012h bit 29 */

#define CO_TIME_MS_PER_DAY 86400000u
#define CO_TIME_MS_MASK 0x0FFFFFFFu /* 28 bits */
/* 1984-01-01T00:00:00Z as seconds since the Unix epoch. */
#define CO_TIME_EPOCH_UNIX_S 441763200LL
#define CO_TIME_FRAME_LEN 6u

typedef struct co_time_of_day {
	uint32_t ms;   /* milliseconds after midnight, < CO_TIME_MS_PER_DAY */
	uint16_t days; /* days since 1984-01-01 */
} co_time_of_day;

/* Write the 6 wire bytes. -EINVAL if t->ms >= CO_TIME_MS_PER_DAY. */
int co_time_encode(const co_time_of_day *t, uint8_t out[CO_TIME_FRAME_LEN]);
/* Read the 6 wire bytes (reserved bits ignored). -EINVAL if len < 6 or the
 * milliseconds are >= one day. */
int co_time_decode(const uint8_t *in, uint32_t len, co_time_of_day *t);
/* Unix time (ms, UTC) <-> TIME_OF_DAY. -ERANGE outside 1984..2163. */
int co_time_from_unix_ms(int64_t unix_ms, co_time_of_day *t);
int64_t co_time_to_unix_ms(const co_time_of_day *t);

typedef struct co_time_stats {
	uint64_t tx;         /* TIME frames produced */
	uint64_t rx;         /* TIME frames consumed (CO_EV_TIME emitted) */
	uint64_t rx_invalid; /* short frame or ms out of range: ignored */
	uint64_t rx_ignored; /* received in STOPPED / INITIALISING */
} co_time_stats;

extern const co_service co_svc_time;

/*
 * Produce one TIME frame with t; once sent, CO_EV_TIME with produced = 1
 * (as the SYNC producer reports its own SYNCs). Returns 0, -EINVAL (bad t), -EPERM (1012h
 * bit 30 clear or no 1012h), -EAGAIN (NMT state is not PRE-OPERATIONAL or
 * OPERATIONAL), -ENODEV (no TIME service), or the send callback's error.
 */
int co_time_send(co_node *node, const co_time_of_day *t, uint64_t now_us);
/* Last TIME consumed; -ENODATA if none yet. */
int co_time_last(const co_node *node, co_time_of_day *t);
const co_time_stats *co_time_get_stats(const co_node *node);

/* Add 1012h (UNSIGNED32 rw, default cob_id; 0 = 100h) unless present. */
int co_od_add_comm_defaults_time(co_od *od, uint32_t cob_id);

#endif /* COGW_CORE_TIME_H */
