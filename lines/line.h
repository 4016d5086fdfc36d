/* SPDX-License-Identifier: MIT */
/*
 * lines/line.h - one CAN line at run time: its real-time thread, which owns
 * the line's core instance, SocketCAN port and mailbox server.
 *
 * The thread sleeps in epoll on: the CAN socket, one timerfd armed at the
 * earliest deadline (core, mailbox, transmit retry, watchdog check-in,
 * extensions), the line's mailbox command queue, an eventfd through which
 * the main thread wakes it, and each extension's wake_fd (cross-line rings,
 * lines/xring.h). Nothing else touches the line's core instance: every
 * request reaches it as a message. Extensions (manager, gateway) plug in
 * through line_params.ext, see lines/line_ext.h.
 *
 * Threads: line_create/line_start/line_stop/line_destroy are for the main
 * thread; line_last_checkin_us, line_stats_snapshot and the line_request_*
 * calls may be made from any thread and never block the line thread.
 */
#ifndef COGW_LINES_LINE_H
#define COGW_LINES_LINE_H

#include <stdbool.h>
#include <stdint.h>

#include "core/appwd.h"
#include "core/co.h"
#include "lines/line_ext.h"
#include "lines/socketcan.h"
#include "mailbox/server.h"

typedef struct line line;

#define LINE_SAFE_OUTPUTS_MAX 32

/* Nodes outside the configuration (lines/line_scan.c, docs/config.md
 * "unknown_nodes"). */
typedef struct line_unknown_params {
	uint8_t policy;          /* enum mbx_unknown_policy */
	uint16_t heartbeat_ms;   /* supervise, boot: its 1016h consumer time
	                          * (0 = none) */
	uint16_t sdo_timeout_ms; /* per SDO frame of identity reads and scans
	                          * (0 = LINE_SCAN_TIMEOUT_MS) */
	bool identify;           /* read an unknown node's identity; false: reported
	                * without (another SDO client, a configuration tool,
	                * talks to new nodes) */
	uint32_t known[4];       /* the configured node-IDs: bit n % 32 of
	                          * known[n / 32] */
} line_unknown_params;

#define LINE_SCAN_TIMEOUT_MS 100u

/* An object of the line's OD that a client may own (docs/application.md):
 * the object exists (the configuration's "objects"), in 2000h..9FFFh. */
typedef struct line_app_decl {
	uint16_t index;
	uint8_t sub;
	uint8_t kind; /* mbx_app_kind */
	uint32_t uid; /* the user whose clients may claim it */
} line_app_decl;

/* Objects clients own (lines/line_app.c); 0 = the default in brackets. */
typedef struct line_app_params {
	const line_app_decl *decl; /* copied by line_create */
	uint16_t n_decl;
	uint16_t max_created;        /* objects created at run time, all clients (100) */
	uint16_t max_per_client;     /* objects one client owns (64) */
	uint16_t max_ind_per_client; /* indications open to one owner (8) */
} line_app_params;

typedef struct line_params {
	uint8_t index;              /* line number, as in mailbox messages */
	const char *name;           /* "line0", for logs */
	uint16_t network_id;        /* CiA 302-7 network id of this line */
	can_port_config can;        /* interface, bit rate, queue sizes */
	co_node_config node;        /* node id, OD (owned by the caller), SDO
	                           * settings; send/event are set by the line */
	mbx_server_config mbx;      /* queue name, limits, access rules;
	                           * dispatch is set by the line */
	int rt_priority;            /* SCHED_FIFO 1..99, 0 = normal */
	int rt_cpu;                 /* CPU to pin to, -1 = any */
	unsigned checkin_ms;        /* watchdog check-in period (default 500) */
	unsigned time_period_ms;    /* TIME producer period (lines/line_time.c);
	                             * 0 = the line produces no TIME */
	const char *state_dir;      /* where 1010h "save" persists (NULL = off) */
	int main_wakefd;            /* eventfd the line writes to when the main
	                           * thread has storage work (-1 = none) */
	line_ext ext[LINE_EXT_MAX]; /* extensions (lines/line_ext.h), in
	                             * order; entries with ops NULL unused */
	co_pdo_layout *pdo_layout;  /* the slaves' learned PDO layouts
	                             * (core/pdo_layout.h), used by the line's
	                             * extensions on its thread; owned by the
	                             * caller, outlives the line; NULL = none */
	/* bus health (lines/line_health.c): an episode is over after this
	 * silence; 0 = the default */
	uint32_t id_conflict_quiet_ms; /* a node-ID collision (5000) */
	uint32_t fault_quiet_ms;       /* lost frames (1000) */
	/* the application watchdog and host ready (lines/line_appwd.c,
	 * docs/application.md) */
	co_safe_output safe_outputs[LINE_SAFE_OUTPUTS_MAX];
	uint8_t n_safe_outputs;
	uint32_t app_reactions; /* the configured set (core/appwd.h), 0 = none */
	uint8_t not_ready_cs;   /* the NMT command host not ready sends to all
	                         * nodes: stop or enter pre-operational (0 = stop) */
	line_unknown_params unknown;
	line_app_params app; /* objects clients own */
} line_params;

/* Counters published by the line thread about once per second. */
typedef struct line_stats {
	uint64_t loops;
	uint64_t rx_frames, tx_frames;
	uint64_t rx_error_frames, rx_overflow_drops;
	uint64_t tx_drops, tx_errors;
	uint64_t core_rx_invalid, core_tx_failed;
	uint32_t bus_load_permille;
	uint8_t bus_state;   /* can_bus_state */
	uint8_t nmt_state;   /* our own NMT state */
	uint16_t nodes_seen; /* remote nodes heard (boot-up/heartbeat) */
	uint32_t mbx_clients;
	uint64_t mbx_commands, mbx_malformed, mbx_denied, mbx_dropped;
	uint64_t events_sent;
	uint64_t max_loop_us; /* longest loop iteration seen (one loop in 64 timed) */
} line_stats;

/* Open the port, create the node and the mailbox server. Returns 0 or
 * -errno and logs the reason ("line line0 (vcan0): ..."). */
int line_create(line **out, const line_params *p);
/* Start the thread (RT settings applied; logs when not permitted). */
int line_start(line *l);
/* Ask the thread to stop, wake it and join it. Idempotent. */
void line_stop(line *l);
void line_destroy(line *l); /* stops first; accepts NULL */

const char *line_name(const line *l);
/* CLOCK_MONOTONIC µs of the line thread's last loop iteration. */
uint64_t line_last_checkin_us(const line *l);
/* Bytes of buffers the line allocated at create (SDO transfer buffers,
 * the store buffer, its mailbox's transfer slots): what mlockall would
 * pin once touched. Any thread, after line_create. */
size_t line_buffer_bytes(const line *l);
bool line_is_up(const line *l);
/* Can frames go out on this line and be answered: the line is up, not
 * bus-off (its own CAN state, no lock) and its interface is up and running
 * (can_port_link_up). Line thread only (its extensions): a caller about to
 * send and wait. */
bool line_can_carry(const line *l);
/* Line thread only: a count that moves whenever what line_can_carry
 * answers may have changed (a CAN bus state change, a receive error such
 * as ENETDOWN when the interface goes down), so that a caller can look
 * again at once instead of polling the interface. */
uint32_t line_link_events(const line *l);
/* The CAN interface's name (line_params.can.ifname). */
const char *line_ifname(const line *l);
/* On the line thread: nothing waits in the transmit queue and the
 * controller is not bus-off (a frame sent now leaves at once). */
bool line_tx_idle(const line *l);
/* On the line thread: data frames with these identifiers are this line's
 * own TPDOs sent by another thread (the gateway's forwarding fast path):
 * the line does not receive them, as it does not receive what it sends
 * itself (can_port_ignore_data). 0 or -errno. */
int line_ignore_own_tpdos(line *l, const co_frame *ids, size_t n);
/* Copy the latest published counters. Returns false if none yet. */
bool line_stats_snapshot(line *l, line_stats *out);

/* Requests from the main thread (served by the line thread). */
void line_request_stall(line *l, unsigned ms);       /* test hook */
void line_request_hb_producer(line *l, uint16_t ms); /* reload */
/* Reload: new mailbox access rules, default access and lease (applied by
 * the line thread with mbx_server_set_rules/_set_lease, also to clients
 * already registered). Waits up to ~1 s for the line to apply them.
 * Returns 0 (applied), -EINVAL (too many rules), -EBUSY (the previous
 * request is still pending: nothing posted) or -ETIMEDOUT (posted, the
 * line will apply it when it loops again). */
/* A node added, changed or removed at run time (reload; lines/line_ext.h
 * line_node_set, docs/config.md "Nodes at run time"): handed to the line
 * thread, which applies it through its extensions. Waits until it is
 * applied and returns its result: 0, a negative errno of the extension,
 * -EOPNOTSUPP (no extension keeps a network list), -ETIMEDOUT (the line
 * did not take it within a second: it may still apply it; set->cdcf and
 * set->types must stay valid), -EBUSY (an earlier one is still pending).
 * Main thread only. */
int line_request_node(line *l, const line_node_set *set);
/* A heartbeat consumer of "heartbeat_consumers" (1016h) at run time: the
 * entry of `node` set to time_ms (0 = no longer consumed), written by the
 * line thread (reload). Results as line_request_node; -ENOSPC when 1016h
 * has no free entry. Main thread only. */
int line_request_consumer(line *l, uint8_t node, uint16_t time_ms);
/* The line thread's scheduling (lines[].rt) at run time: SCHED_FIFO at
 * priority (0 = normal scheduling), pinned to cpu (-1 = none). 0 or
 * -errno (-EPERM without CAP_SYS_NICE). Main thread only. */
int line_set_rt(line *l, int priority, int cpu);
int line_request_access(line *l, const mbx_access_rule *rules, size_t n_rules,
			uint8_t default_access, unsigned lease_ms);

/* Main thread: carry out a pending 1010h save / 1011h restore for this
 * line (file I/O, which the line thread never does). Returns true if there
 * was one. */
bool line_store_service(line *l);

/* Monotonic clock in µs (the one clock every line reads once per loop). */
uint64_t line_now_us(void);

#endif /* COGW_LINES_LINE_H */
