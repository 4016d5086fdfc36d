/* SPDX-License-Identifier: MIT */
/*
 * core/nmt.h - network management: the node's own NMT state machine (NMT
 * slave, CiA 301 §7.3.2) and the NMT master's command sender (§7.2.8.3.1).
 *
 * Slave
 * - States use the heartbeat byte values (enum co_nmt_state).
 * - Start-up: the node is INITIALISING after co_node_create(); its first
 *   co_node_tick() (the NMT service asks for a deadline of 0) sends the
 *   boot-up message 700h + id [00] and enters PRE-OPERATIONAL. The same
 *   happens after every reset communication / reset application, whether
 *   it came from an NMT command, from co_nmt_local_cmd() or from the
 *   application calling co_node_reset_comm() directly. A node with id 255
 *   (LSS unconfigured) stays INITIALISING and sends no boot-up.
 * - NMT commands arrive on COB-ID 000h as [cs, node]; node 0 = all. Frames
 *   with a length other than 2 are ignored (counted). cs: 01h start, 02h
 *   stop, 80h enter pre-operational, 81h reset node (application), 82h
 *   reset communication.
 * - The application may veto OPERATIONAL (co_nmt_set_veto); the node then
 *   stays where it was.
 * - Every state change emits CO_EV_NMT_STATE and calls every service's
 *   nmt_changed op (co_node_nmt_changed, co.h): PDO runs only in
 *   OPERATIONAL, EMCY/SDO not in STOPPED, ...
 * - 1029h sub 1 (communication error behaviour) is applied by
 *   co_nmt_comm_error(): 0 = enter PRE-OPERATIONAL (only from OPERATIONAL),
 *   1 = no change, 2 = enter STOPPED. Without 1029h: behaviour 0.
 *
 * Master
 * - co_nmt_master_send() queues [cs, target] on COB-ID 000h. 102Ah (NMT
 *   inhibit time, UNSIGNED16, 100 us units) spaces successive NMT frames:
 *   a frame produced within the inhibit time waits in a bounded queue
 *   (CO_NMT_MASTER_QUEUE_LEN); -ENOBUFS when it is full, nothing dropped
 *   silently. With CO_NMT_SEND_SELF and target 0 the command also applies
 *   to this node, right after the frame has gone out.
 *
 * All functions: owning thread only; 0 or a negative errno.
 */
#ifndef COGW_CORE_NMT_H
#define COGW_CORE_NMT_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"

#define CO_NMT_COB_ID 0x000u
#define CO_NMT_ERRCTRL_BASE 0x700u /* boot-up, heartbeat, guarding */
#define CO_NMT_MASTER_QUEUE_LEN 16u

/* NMT states, valued as in the heartbeat / guarding byte (bits 6..0). */
typedef enum co_nmt_state {
	CO_NMT_INITIALISING = 0x00, /* also the boot-up message */
	CO_NMT_STOPPED = 0x04,
	CO_NMT_OPERATIONAL = 0x05,
	CO_NMT_PRE_OPERATIONAL = 0x7F,
} co_nmt_state;

/* "initialising", "stopped", "operational", "pre-operational", "?" */
const char *co_nmt_state_to_string(uint8_t state);

/* NMT command specifiers (byte 0 of the NMT frame). */
typedef enum co_nmt_cs {
	CO_NMT_CS_START = 0x01,
	CO_NMT_CS_STOP = 0x02,
	CO_NMT_CS_ENTER_PREOP = 0x80,
	CO_NMT_CS_RESET_NODE = 0x81,
	CO_NMT_CS_RESET_COMM = 0x82,
} co_nmt_cs;

/* "start", "stop", "enter-pre-operational", "reset-node", "reset-comm". */
const char *co_nmt_cs_to_string(uint8_t cs);
bool co_nmt_cs_is_valid(uint8_t cs);

/* Values of 1029h subs (error behaviour). */
enum co_nmt_err_behaviour {
	CO_NMT_ERR_PREOP = 0, /* to PRE-OPERATIONAL if OPERATIONAL */
	CO_NMT_ERR_NO_CHANGE = 1,
	CO_NMT_ERR_STOPPED = 2,
};

typedef struct co_nmt_stats {
	uint64_t cmd_rx;          /* NMT commands addressed to us */
	uint64_t cmd_invalid;     /* wrong length / unknown cs */
	uint64_t vetoed;          /* OPERATIONAL refused by the application */
	uint64_t cmd_filtered;    /* received commands the rx filter dropped */
	uint64_t master_tx;       /* NMT frames sent as master */
	uint64_t master_queued;   /* had to wait for 102Ah */
	uint64_t master_overflow; /* refused: queue full */
} co_nmt_stats;

extern const co_service co_svc_nmt;

uint8_t co_nmt_get_state(const co_node *node);

/*
 * Veto hook: called before the node enters OPERATIONAL (from an NMT
 * command or co_nmt_local_cmd). Return true to allow, false to stay.
 * NULL removes it.
 */
typedef bool (*co_nmt_veto_fn)(void *ctx, co_node *node, uint8_t from_state, uint8_t to_state);
void co_nmt_set_veto(co_node *node, co_nmt_veto_fn fn, void *ctx);

/*
 * Receive filter: called for every valid NMT command from the bus that
 * addresses this node (target = own id or 0) before it is applied. Return
 * false to ignore it (counted in cmd_filtered). The CiA 302-2 manager uses
 * it so that other nodes cannot stop or reset the NMT master. Local
 * commands (co_nmt_local_cmd) do not pass through it. NULL removes it.
 */
typedef bool (*co_nmt_rx_filter_fn)(void *ctx, co_node *node, uint8_t cs, uint8_t target,
				    uint64_t now_us);
void co_nmt_set_rx_filter(co_node *node, co_nmt_rx_filter_fn fn, void *ctx);

/* Apply an NMT command to this node as if it had been received (the
 * application starting itself, a self-starting device). -EINVAL for an
 * unknown cs; a vetoed start returns -EPERM. */
int co_nmt_local_cmd(co_node *node, uint8_t cs, uint64_t now_us);

/* Master: send [cs, target] (target 0 = all nodes, 1..127). */
#define CO_NMT_SEND_SELF 0x1u /* target 0: also apply to this node */
int co_nmt_master_send(co_node *node, uint8_t target, uint8_t cs, uint64_t now_us);
int co_nmt_master_send_ex(co_node *node, uint8_t target, uint8_t cs, unsigned flags,
			  uint64_t now_us);
/* Frames waiting for the NMT inhibit time. */
unsigned co_nmt_master_pending(const co_node *node);

/*
 * 1029h: a communication error happened (heartbeat consumer timeout, life
 * guarding, bus-off). Applies sub 1; see the file comment. Returns the
 * behaviour applied (CO_NMT_ERR_*).
 */
int co_nmt_comm_error(co_node *node, uint64_t now_us);
/* Same for any 1029h sub (2.. = device profile / manufacturer errors). */
int co_nmt_error_behaviour(co_node *node, uint8_t sub, uint64_t now_us);

const co_nmt_stats *co_nmt_get_stats(const co_node *node);

/*
 * Add 1029h (ARRAY of U8, sub 1 = communication error, default 0; n_subs
 * 1..254) and 102Ah (U16 rw, default 0) unless present.
 */
int co_od_add_comm_defaults_nmt(co_od *od, uint8_t n_subs);

#endif /* COGW_CORE_NMT_H */
