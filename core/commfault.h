/* SPDX-License-Identifier: MIT */
/*
 * core/commfault.h - communication faults of the node itself: the CAN
 * controller's error states, frames lost on receive or transmit, and
 * another device on our node-ID. Each fault runs in episodes: the first
 * occurrence begins one (EMCY with the CiA 301 code, an event, counters),
 * its end clears the EMCY again (the error reset 0000h when no other error
 * stays active, CiA 301 §7.2.7), one event; occurrences in between are
 * counted only (docs/troubleshooting.md).
 *
 * How an episode ends depends on the fault:
 * - by the controller's state (warning, passive, bus-off): the line reports
 *   every state change with co_commfault_bus_state(); a level fault is
 *   active while the controller is at that level or worse;
 * - by silence (frames lost, node-ID collision): no occurrence for the
 *   quiet time of that fault (co_commfault_set_quiet_ms).
 *
 * | fault          | EMCY at the begin            | at the end            |
 * |----------------|------------------------------|-----------------------|
 * | ID_COLLISION   | 8150h, msef[0] = state heard | cleared               |
 * | WARNING        | none (CiA 301 has no code)   | -                     |
 * | PASSIVE        | 8120h                        | cleared               |
 * | BUS_OFF        | none (nothing can be sent);  | 8140h "recovered from |
 * |                | 1029h:1 applies              | bus-off", then cleared|
 * | RX_OVERRUN     | 8110h, msef[0] = 1           | cleared with TX_LOST  |
 * | TX_LOST        | 8110h, msef[0] = 2           | cleared with RX_OVERRUN|
 *
 * The node-ID collision is found here: a boot-up or heartbeat (a data
 * frame of one byte holding an NMT state, CiA 301 §7.2.8.3.2) on 700h + our
 * own node-ID comes from another device, since node-IDs are unique and a
 * CAN controller does not receive its own frames. The other faults come
 * from the line runtime, which sees the controller.
 *
 * Pure code, owning thread only. Functions return 0 or a negative errno.
 */
#ifndef COGW_CORE_COMMFAULT_H
#define COGW_CORE_COMMFAULT_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"

extern const co_service co_svc_commfault;

typedef enum co_comm_fault {
	CO_COMM_FAULT_ID_COLLISION = 0, /* another device on our node-ID */
	CO_COMM_FAULT_WARNING,          /* controller at the warning limit or worse */
	CO_COMM_FAULT_PASSIVE,          /* controller error passive or worse */
	CO_COMM_FAULT_BUS_OFF,          /* controller bus-off */
	CO_COMM_FAULT_RX_OVERRUN,       /* received frames lost (controller or
	                                 * socket queue) */
	CO_COMM_FAULT_TX_LOST,          /* frames not delivered: no ACK,
	                                 * transmit time-out, transmit queue full */
	CO_COMM_FAULT_COUNT
} co_comm_fault;

/* "id-collision", "warning", "passive", "bus-off", "rx-overrun", "tx-lost" */
const char *co_comm_fault_to_string(uint8_t fault);

/* Controller state as the line reports it (co_commfault_bus_state). */
typedef enum co_bus_level {
	CO_BUS_LEVEL_ACTIVE = 0,
	CO_BUS_LEVEL_WARNING,
	CO_BUS_LEVEL_PASSIVE,
	CO_BUS_LEVEL_BUS_OFF,
} co_bus_level;

/* Default quiet times (ms) of the faults that end by silence. The
 * collision's must exceed the other device's heartbeat period. */
#define CO_COMMFAULT_ID_COLLISION_QUIET_MS 5000u
#define CO_COMMFAULT_LOST_QUIET_MS 1000u

typedef struct co_commfault_stats {
	bool active;
	uint32_t episodes;    /* begun since the counters were reset */
	uint32_t occurrences; /* frames / reports since the counters were reset */
	uint64_t since_us;    /* begin of the running (or last) episode */
	uint64_t last_us;     /* last occurrence */
	uint8_t info;         /* ID_COLLISION: the state byte last heard */
} co_commfault_stats;

/* One occurrence of a fault that ends by silence (RX_OVERRUN, TX_LOST;
 * ID_COLLISION is found by the node itself but may be reported too).
 * count: frames lost in it (>= 1). -EINVAL for a level fault. */
int co_commfault_occurred(co_node *node, co_comm_fault fault, uint32_t count, uint64_t now_us);
/* The controller's state changed: the level faults follow it (begin, end,
 * bus-off's 1029h:1 and 8140h). -ENODEV without the service. */
int co_commfault_bus_state(co_node *node, co_bus_level level, uint64_t now_us);
/* Quiet time of a fault that ends by silence, 1..3600000 ms. */
int co_commfault_set_quiet_ms(co_node *node, co_comm_fault fault, uint32_t quiet_ms);

/* NULL for a bad fault or without the service. */
const co_commfault_stats *co_commfault_get(const co_node *node, co_comm_fault fault);
/* Zero episodes and occurrences of every fault (running episodes go on). */
void co_commfault_reset_counters(co_node *node);

/* A boot-up or heartbeat message (CiA 301 §7.2.8.3.2): a data frame of one
 * byte holding an NMT state (bit 7, the guarding toggle, ignored). */
bool co_commfault_is_errctrl_message(const co_frame *f);

#endif /* COGW_CORE_COMMFAULT_H */
