/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/support/membus.h - an in-memory CAN bus for unit tests.
 *
 * Every frame a node sends is queued and then delivered to every other
 * node on the bus (never back to the sender, like a CAN controller without
 * self-reception), in send order. Delivery happens in membus_run(), never
 * inside the send callback, so a node is never re-entered from its own
 * send. The bus owns the clock: membus_advance() steps it to the next
 * node deadline, ticks, delivers, and repeats, so timers fire exactly at
 * their deadlines without sleeping.
 *
 * Every frame on the bus is also kept in a log (sender index, time) for
 * byte-by-byte assertions. A test can play a scripted node with
 * membus_inject() (sender index MEMBUS_SCRIPT, delivered to all nodes).
 *
 * Usage:
 *   membus bus; membus_init(&bus);
 *   cfg.send = membus_send; cfg.send_ctx = membus_port_new(&bus);
 *   co_node_create(&n, &cfg); membus_bind(&bus, n);  (same order as ports)
 */
#ifndef COGW_TESTS_MEMBUS_H
#define COGW_TESTS_MEMBUS_H

#include <stdbool.h>
#include <stdint.h>

#include "core/co.h"

#define MEMBUS_MAX_NODES 8
#define MEMBUS_QUEUE_LEN 512
#define MEMBUS_LOG_LEN 4096
#define MEMBUS_SCRIPT (-1) /* sender index of injected frames */

typedef struct membus membus;

typedef struct membus_port {
	membus *bus;
	int idx;
} membus_port;

typedef struct membus_entry {
	co_frame f;
	int from;      /* port index, MEMBUS_SCRIPT for injected frames */
	uint64_t t_us; /* bus time when sent */
} membus_entry;

struct membus {
	uint64_t now_us;
	membus_port ports[MEMBUS_MAX_NODES];
	co_node *nodes[MEMBUS_MAX_NODES];
	unsigned n_ports;
	unsigned n_bound;
	membus_entry queue[MEMBUS_QUEUE_LEN];
	unsigned q_head, q_count;
	membus_entry log[MEMBUS_LOG_LEN];
	unsigned n_log;
	bool fail_send; /* make every send fail with -ENOBUFS */
};

void membus_init(membus *bus);
/* A new port: pass it as send_ctx, then bind the node created with it. */
membus_port *membus_port_new(membus *bus);
void membus_bind(membus *bus, co_node *node);
/* co_send_fn */
int membus_send(void *ctx, const co_frame *f);
/* Put a frame on the bus as a scripted node (id 11-bit, 8 bytes given). */
void membus_inject(membus *bus, uint32_t id, const uint8_t data[8]);
/* Deliver queued frames (and whatever they cause) until the bus is idle. */
void membus_run(membus *bus);
/* Step the clock to t_us, firing every deadline on the way. */
void membus_advance(membus *bus, uint64_t t_us);
/* Step by dt_us. */
void membus_advance_by(membus *bus, uint64_t dt_us);
/* Log entries with this COB-ID from index `from` on; -1 if none. */
int membus_log_find(const membus *bus, unsigned from, uint32_t id);
/* Log index of the n-th (0-based) frame with this COB-ID; -1 if none. */
int membus_log_nth(const membus *bus, uint32_t id, unsigned n);
/* Number of logged frames with this COB-ID. */
unsigned membus_log_count(const membus *bus, uint32_t id);

/* A simple event recorder (event callback + ctx). */
#define EVLOG_LEN 512
typedef struct evlog {
	co_event ev[EVLOG_LEN];
	unsigned n;
} evlog;
void evlog_fn(void *ctx, const co_event *ev);
/* Index of the first event of this kind at or after from; -1 if none. */
int evlog_find(const evlog *log, unsigned from, co_event_kind kind);
unsigned evlog_count(const evlog *log, co_event_kind kind);

#endif /* COGW_TESTS_MEMBUS_H */
