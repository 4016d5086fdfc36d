/* SPDX-License-Identifier: MIT */
/*
 * core/guarding.h - node guarding and life guarding (CiA 301 §7.2.8.3.2.1,
 * objects 100Ch guard time, 100Dh life time factor). RTR based and
 * deprecated by CiA AN802; kept for old slaves a manager must still serve.
 *
 * Slave (life guarding)
 * - The master sends an RTR on 700h + id; we answer one byte:
 *   bit 7 = toggle (0 in the first answer after a reset, then alternating),
 *   bits 6..0 = NMT state. While 1017h != 0 the heartbeat is in use and
 *   RTRs are not answered (CiA 301: a device uses one of the two).
 * - Life guarding is active once 100Ch and 100Dh are both != 0 and the
 *   first RTR has arrived. No RTR within 100Ch x 100Dh ms ->
 *   CO_EV_GUARD_LIFE_LOST, EMCY 8130h, 1029h:1 behaviour. The next RTR ->
 *   CO_EV_GUARD_LIFE_RESUMED.
 *
 * Master (node guarding)
 * - co_guard_master_add() polls a node every guard time with an RTR on
 *   700h + node and checks each answer: a repeated toggle bit gives
 *   CO_EV_GUARD_TOGGLE (the node is alive, so the answer still counts; the
 *   check resynchronises on it); no valid answer within the node life
 *   time (guard time x life factor, from the last answer or from
 *   co_guard_master_add) gives CO_EV_GUARD_FAILED (once), the next answer
 *   CO_EV_GUARD_RESUMED; a changed state byte gives CO_EV_HB_STATE with
 *   guarded = 1.
 *
 * All functions: owning thread only; 0 or a negative errno.
 */
#ifndef COGW_CORE_GUARDING_H
#define COGW_CORE_GUARDING_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"

extern const co_service co_svc_guard;

#define CO_GUARD_TOGGLE 0x80u

/* Start guarding `target` (1..127): first RTR now, then every
 * guard_time_ms (> 0); life_factor 0 counts as 1. Re-adding updates the
 * timing. -EINVAL, -ENOSPC (no receiver left). */
int co_guard_master_add(co_node *node, uint8_t target, uint16_t guard_time_ms, uint8_t life_factor,
			uint64_t now_us);
int co_guard_master_remove(co_node *node, uint8_t target);
bool co_guard_master_has(const co_node *node, uint8_t target);
/* Master: guarded node currently failed. */
bool co_guard_master_failed(const co_node *node, uint8_t target);
/* Slave: life guarding active (timer running) / lost. */
bool co_guard_life_active(const co_node *node);
bool co_guard_life_lost(const co_node *node);

/* Add 100Ch (U16 rw, 0) and 100Dh (U8 rw, 0) unless present. */
int co_od_add_comm_defaults_guard(co_od *od);

#endif /* COGW_CORE_GUARDING_H */
