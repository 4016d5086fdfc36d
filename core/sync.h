/* SPDX-License-Identifier: MIT */
/*
 * core/sync.h - SYNC producer and consumer (CiA 301 §7.2.5).
 *
 * Objects (all optional; co_od_add_comm_defaults_sync() creates them):
 *   1005h COB-ID SYNC (UNSIGNED32): bit 30 = this node produces SYNC,
 *         bit 29 = 29-bit CAN-ID. The CAN-ID cannot change while bit 30 is
 *         set (0x06090030). Without 1005h: consumer on 80h, never producer.
 *   1006h communication cycle period (UNSIGNED32, µs): 0 = no SYNC produced.
 *   1007h synchronous window length (UNSIGNED32, µs): 0 = no window. After
 *         the window has closed, synchronous RPDOs are discarded until the
 *         next SYNC (CiA 301 §7.2.5.2 allows this; a late sample would be
 *         applied one cycle late, which is worse than none).
 *   1019h synchronous counter overflow value (UNSIGNED8): 0 = the SYNC has
 *         no data; 2..240 = it carries a counter 1..value. 1 and 241..255
 *         are refused (0x06090030); writing it while 1006h != 0 is refused
 *         with 0x08000022 (CiA 301 §7.5.2.22).
 *
 * Producer: active iff 1005h bit 30 and 1006h > 0, in PRE-OPERATIONAL and
 * OPERATIONAL (not STOPPED). The first SYNC goes out one period after the
 * producer (re)starts (NMT state change, 1005h/1006h written); the counter
 * restarts at 1 then. Deadlines step by exactly one period (no drift); a
 * tick that comes later than one whole period skips the missed SYNCs
 * rather than sending a burst.
 *
 * Consumer: every SYNC on the 1005h CAN-ID (ignored while we produce, and
 * in STOPPED). With 1019h > 0 the frame must carry exactly one byte; other
 * lengths are dropped and EMCY 8240h (SYNC data length) is raised. With
 * 1019h = 0 any counter byte is ignored (CiA 301: no counter expected).
 *
 * On every SYNC, produced or consumed, in this order:
 *   1. CO_EV_SYNC (counter, produced) - the callback may still update
 *      mapped objects, synchronous TPDOs sample after it returns;
 *   2. every SYNC observer (co_sync_observer_add), in registration order:
 *      the PDO service registers one at init that commits synchronous
 *      RPDOs and sends synchronous TPDOs (core/pdo.h, co_pdo_sync_ind).
 *
 * All functions: owning thread only.
 */
#ifndef COGW_CORE_SYNC_H
#define COGW_CORE_SYNC_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"

#define CO_SYNC_COB_DEFAULT 0x80u
#define CO_SYNC_PRODUCER 0x40000000u /* 1005h bit 30 */
#define CO_SYNC_EXT CO_COB_EXT       /* 1005h bit 29 */
#define CO_SYNC_COUNTER_MAX 240u

typedef struct co_sync_stats {
	uint64_t tx;         /* SYNC frames produced */
	uint64_t rx;         /* SYNC frames consumed */
	uint64_t rx_invalid; /* wrong length (EMCY 8240h) */
	uint64_t rx_ignored; /* while producing, or in STOPPED/INITIALISING */
	uint64_t skipped;    /* producer periods skipped by a late tick */
} co_sync_stats;

extern const co_service co_svc_sync;

/* Something that acts on every SYNC, produced or consumed: called after
 * CO_EV_SYNC with the SYNC's counter (0 = none). */
typedef void (*co_sync_ind_fn)(co_node *node, void *ctx, uint8_t counter, uint64_t now_us);

#define CO_SYNC_OBSERVERS_MAX 4

/* Register an observer for the node's lifetime (services call it from
 * their init op; co_svc_sync runs before them). 0, -EINVAL, -ENODEV,
 * -ENOSPC (CO_SYNC_OBSERVERS_MAX reached). */
int co_sync_observer_add(co_node *node, co_sync_ind_fn fn, void *ctx);

/* Counter of the last SYNC (0 = none yet, or SYNC without counter). */
uint8_t co_sync_counter(const co_node *node);
/* 1019h value in force (0 = no counter). */
uint8_t co_sync_overflow(const co_node *node);
/* True if the node currently produces SYNC. */
bool co_sync_is_producer(const co_node *node);
/* Time of the last SYNC; CO_NO_DEADLINE if none since the last reset. */
uint64_t co_sync_last_us(const co_node *node);
/* True if now_us is inside the synchronous window of the last SYNC (always
 * true with 1007h = 0 or absent; false before the first SYNC when a window
 * is configured). */
bool co_sync_in_window(const co_node *node, uint64_t now_us);
const co_sync_stats *co_sync_get_stats(const co_node *node);

/* Add 1005h (U32 rw, cob_id; 0 = 80h), 1006h (U32 rw, period_us), 1007h
 * (U32 rw, 0) and 1019h (U8 rw, overflow) unless present. */
int co_od_add_comm_defaults_sync(co_od *od, uint32_t cob_id, uint32_t period_us, uint8_t overflow);

#endif /* COGW_CORE_SYNC_H */
