/* SPDX-License-Identifier: MIT */
#include "tests/unit/support/errctrl_fixture.h"

#include <assert.h>
#include <string.h>

#include "core/emcy.h"
#include "core/guarding.h"
#include "core/heartbeat.h"
#include "core/nmt.h"

static int ecf_send(void *ctx, const co_frame *f)
{
	ecf *x = ctx;

	if (x->n_tx < ECF_LOG) {
		x->tx_t[x->n_tx] = x->now;
		x->tx[x->n_tx++] = *f;
	}
	return 0;
}

co_od *ecf_od_std(uint8_t node_id)
{
	co_od *od = NULL;
	int rc = co_od_create(&od, 64);

	assert(rc == 0);
	rc = co_od_add_num(od, 0x1000, 0, CO_T_UNSIGNED32, CO_ACC_RO, 0x191, NULL);
	assert(rc == 0);
	rc = co_od_add_comm_defaults_emcy(od, node_id, 8, 4, 1);
	assert(rc == 0);
	rc = co_od_add_comm_defaults_hb(od, 4, 0);
	assert(rc == 0);
	rc = co_od_add_comm_defaults_nmt(od, 2);
	assert(rc == 0);
	rc = co_od_add_comm_defaults_guard(od);
	assert(rc == 0);
	return od;
}

void ecf_create(ecf *x, uint8_t node_id, co_od *od)
{
	co_node_config cfg;
	int rc;

	memset(x, 0, sizeof(*x));
	x->od = od ? od : ecf_od_std(node_id);
	memset(&cfg, 0, sizeof(cfg));
	cfg.node_id = node_id;
	cfg.od = x->od;
	cfg.send = ecf_send;
	cfg.send_ctx = x;
	cfg.event = evlog_fn;
	cfg.event_ctx = &x->ev;
	rc = co_node_create(&x->node, &cfg);
	assert(rc == 0);
	(void)rc;
}

void ecf_boot(ecf *x, uint8_t node_id)
{
	ecf_create(x, node_id, NULL);
	co_node_tick(x->node, 0);
	ecf_clear(x);
}

void ecf_destroy(ecf *x)
{
	co_node_destroy(x->node);
	co_od_destroy(x->od);
	x->node = NULL;
	x->od = NULL;
}

void ecf_rx(ecf *x, uint32_t id, uint8_t flags, uint8_t len, const uint8_t *data)
{
	co_frame f;

	co_frame_init(&f, id, len);
	f.flags = flags;
	if (data && len)
		memcpy(f.data, data, len);
	co_node_recv(x->node, &f, x->now);
}

void ecf_rx1(ecf *x, uint32_t id, uint8_t byte)
{
	ecf_rx(x, id, 0, 1, &byte);
}

void ecf_advance(ecf *x, uint64_t t)
{
	for (unsigned guard = 0;; guard++) {
		assert(guard < 1000000); /* a deadline that never moves on */
		uint64_t d = co_node_next_deadline_us(x->node);
		if (d > t)
			break;
		if (d > x->now)
			x->now = d;
		co_node_tick(x->node, x->now);
	}
	if (t > x->now)
		x->now = t;
}

void ecf_clear(ecf *x)
{
	x->n_tx = 0;
	x->ev.n = 0;
}

int ecf_tx_find(const ecf *x, unsigned from, uint32_t id)
{
	for (unsigned i = from; i < x->n_tx; i++)
		if (x->tx[i].id == id)
			return (int)i;
	return -1;
}

const co_frame *ecf_tx_last(const ecf *x, uint32_t id)
{
	for (unsigned i = x->n_tx; i-- > 0;)
		if (x->tx[i].id == id)
			return &x->tx[i];
	return NULL;
}

void ecf_sdo_req(ecf *x, const uint8_t req[8])
{
	ecf_rx(x, 0x600u + co_node_id(x->node), 0, 8, req);
}

unsigned ecf_tx_count(const ecf *x, uint32_t id)
{
	unsigned n = 0;

	for (unsigned i = 0; i < x->n_tx; i++)
		n += x->tx[i].id == id;
	return n;
}

int ecf_ev_find(const ecf *x, unsigned from, co_event_kind kind)
{
	return evlog_find(&x->ev, from, kind);
}

unsigned ecf_ev_count(const ecf *x, co_event_kind kind)
{
	return evlog_count(&x->ev, kind);
}
