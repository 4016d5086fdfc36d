/* SPDX-License-Identifier: MIT */
/*
 * core/heartbeat.h - heartbeat producer (1017h) and consumer (1016h) and
 * boot-up reception (CiA 301 §7.2.8.3.2, §7.5.2.18/19). What it shares
 * with node guarding (loss handling) is in core/errctrl.h.
 *
 * Producer
 * - 1017h (UNSIGNED16, ms). Heartbeat = 700h + id, one byte: the NMT state
 *   (04h/05h/7Fh). Sent in PRE-OPERATIONAL, OPERATIONAL and STOPPED; the
 *   boot-up counts as the first one, the next follows one period later.
 * - A write of 1017h (SDO or co_hb_producer_set) applies at once: a value
 *   != 0 sends a heartbeat immediately and restarts the period; 0 stops.
 *
 * Consumer
 * - 1016h sub n: bits 23..16 = node-id, 15..0 = consumer time (ms); 0 in
 *   either field disables the entry. Monitoring of an entry starts with the
 *   first heartbeat from that node (CO_EV_HB_STARTED), not before; a gap of
 *   the consumer time without a heartbeat gives CO_EV_HB_LOST (at or after
 *   last heartbeat + time, never before), EMCY 8130h and the 1029h:1
 *   behaviour. The next heartbeat restarts monitoring (CO_EV_HB_STARTED);
 *   when no loss remains the 8130h error is cleared.
 * - Boot-ups (700h + n, [00]) are seen from every node 1..127, configured
 *   or not: CO_EV_BOOTUP. A boot-up puts that node's entry back to "waiting
 *   for the first heartbeat" (a rebooted node's producer may be off until
 *   it is configured again, so this is not a loss).
 * - Any change of a remote node's state byte gives CO_EV_HB_STATE.
 * - SDO writes of 1016h are checked: two active entries for the same node
 *   give 0x06040043; bits 31..24 set give 0x06090030.
 * - Nodes guarded by this node's guarding master (core/guarding.h, known
 *   through core/errctrl.h) are left to guarding (their replies carry a
 *   toggle bit), except boot-ups.
 *
 * Needs one receiver per node-id (126 of co_node_config.rx_max).
 * All functions: owning thread only; 0 or a negative errno.
 */
#ifndef COGW_CORE_HEARTBEAT_H
#define COGW_CORE_HEARTBEAT_H

#include <stdint.h>

#include "core/co.h"
#include "core/errctrl.h"

extern const co_service co_svc_hb;

#define CO_HB_STATE_UNKNOWN 0xFFu

/* Monitoring status of one consumer entry. */
typedef enum co_hb_mon {
	CO_HB_MON_OFF = 0, /* no entry, or node/time 0 */
	CO_HB_MON_WAITING, /* configured, no heartbeat yet (or after boot-up) */
	CO_HB_MON_ACTIVE,  /* heartbeats arriving in time */
	CO_HB_MON_LOST,    /* consumer time expired */
} co_hb_mon;

const char *co_hb_mon_to_string(co_hb_mon m);

/* Producer: write 1017h (through its hook) and apply it now. -ENOENT
 * without 1017h. */
int co_hb_producer_set(co_node *node, uint16_t period_ms, uint64_t now_us);

/*
 * Consumer: monitor remote_id (1..127) with time_ms. Updates the entry that
 * already names remote_id, else fills a free one (node or time 0).
 * Returns 0, -ENOSPC if 1016h is full, -ENOENT without 1016h, -EINVAL.
 * time_ms 0 disables monitoring of remote_id (the entry stays).
 */
int co_hb_consumer_set(co_node *node, uint8_t remote_id, uint16_t time_ms, uint64_t now_us);

co_hb_mon co_hb_consumer_status(const co_node *node, uint8_t remote_id);
/* Every node whose consumer status is CO_HB_MON_LOST, as a set: bit n%64
 * of lost[n/64] (one pass over 1016h, for a caller that looks often). */
void co_hb_lost_nodes(const co_node *node, uint64_t lost[2]);
/* Last state byte seen from remote_id (any node), CO_HB_STATE_UNKNOWN if
 * none. */
uint8_t co_hb_remote_state(const co_node *node, uint8_t remote_id);
/* Time of the last heartbeat or boot-up frame from remote_id (any node,
 * monitored or not); 0 if none was ever heard. */
uint64_t co_hb_last_heard_us(const co_node *node, uint8_t remote_id);
/* Monitored nodes currently lost. */
unsigned co_hb_lost_count(const co_node *node);

/* Add 1016h (ARRAY, consumers entries 1..127, U32 rw, 0) and 1017h (U16
 * rw, default producer_ms) unless present. consumers 0 = no 1016h. */
int co_od_add_comm_defaults_hb(co_od *od, uint8_t consumers, uint16_t producer_ms);

#endif /* COGW_CORE_HEARTBEAT_H */
