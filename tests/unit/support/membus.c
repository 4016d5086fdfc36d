/* SPDX-License-Identifier: MIT */
#include "tests/unit/support/membus.h"

#include <assert.h>
#include <errno.h>
#include <string.h>

void membus_init(membus *bus)
{
	memset(bus, 0, sizeof(*bus));
}

membus_port *membus_port_new(membus *bus)
{
	assert(bus->n_ports < MEMBUS_MAX_NODES);
	membus_port *p = &bus->ports[bus->n_ports];
	p->bus = bus;
	p->idx = (int)bus->n_ports++;
	return p;
}

void membus_bind(membus *bus, co_node *node)
{
	assert(bus->n_bound < bus->n_ports);
	bus->nodes[bus->n_bound++] = node;
}

static void enqueue(membus *bus, const co_frame *f, int from)
{
	assert(bus->q_count < MEMBUS_QUEUE_LEN);
	membus_entry *e = &bus->queue[(bus->q_head + bus->q_count) % MEMBUS_QUEUE_LEN];
	e->f = *f;
	e->from = from;
	e->t_us = bus->now_us;
	bus->q_count++;
	if (bus->n_log < MEMBUS_LOG_LEN)
		bus->log[bus->n_log++] = *e;
}

int membus_send(void *ctx, const co_frame *f)
{
	membus_port *p = ctx;

	if (p->bus->fail_send)
		return -ENOBUFS;
	enqueue(p->bus, f, p->idx);
	return 0;
}

void membus_inject(membus *bus, uint32_t id, const uint8_t data[8])
{
	co_frame f;

	co_frame_init(&f, id, 8);
	memcpy(f.data, data, 8);
	enqueue(bus, &f, MEMBUS_SCRIPT);
}

void membus_run(membus *bus)
{
	while (bus->q_count) {
		membus_entry e = bus->queue[bus->q_head];
		bus->q_head = (bus->q_head + 1) % MEMBUS_QUEUE_LEN;
		bus->q_count--;
		for (unsigned i = 0; i < bus->n_bound; i++)
			if ((int)i != e.from)
				co_node_recv(bus->nodes[i], &e.f, bus->now_us);
	}
}

void membus_advance(membus *bus, uint64_t t_us)
{
	membus_run(bus);
	for (;;) {
		uint64_t next = CO_NO_DEADLINE;
		for (unsigned i = 0; i < bus->n_bound; i++) {
			uint64_t d = co_node_next_deadline_us(bus->nodes[i]);
			if (d < next)
				next = d;
		}
		if (next > t_us)
			break;
		if (next > bus->now_us)
			bus->now_us = next;
		for (unsigned i = 0; i < bus->n_bound; i++)
			if (co_node_next_deadline_us(bus->nodes[i]) <= bus->now_us)
				co_node_tick(bus->nodes[i], bus->now_us);
		membus_run(bus);
	}
	if (t_us > bus->now_us)
		bus->now_us = t_us;
}

void membus_advance_by(membus *bus, uint64_t dt_us)
{
	membus_advance(bus, bus->now_us + dt_us);
}

int membus_log_find(const membus *bus, unsigned from, uint32_t id)
{
	for (unsigned i = from; i < bus->n_log; i++)
		if (bus->log[i].f.id == id)
			return (int)i;
	return -1;
}

int membus_log_nth(const membus *bus, uint32_t id, unsigned n)
{
	for (unsigned i = 0; i < bus->n_log; i++)
		if (bus->log[i].f.id == id && n-- == 0)
			return (int)i;
	return -1;
}

unsigned membus_log_count(const membus *bus, uint32_t id)
{
	unsigned n = 0;

	for (unsigned i = 0; i < bus->n_log; i++)
		n += bus->log[i].f.id == id;
	return n;
}

void evlog_fn(void *ctx, const co_event *ev)
{
	evlog *log = ctx;

	if (log->n < EVLOG_LEN)
		log->ev[log->n++] = *ev;
}

int evlog_find(const evlog *log, unsigned from, co_event_kind kind)
{
	for (unsigned i = from; i < log->n; i++)
		if (log->ev[i].kind == kind)
			return (int)i;
	return -1;
}

unsigned evlog_count(const evlog *log, co_event_kind kind)
{
	unsigned n = 0;

	for (unsigned i = 0; i < log->n; i++)
		n += log->ev[i].kind == kind;
	return n;
}
