/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/support/errctrl_fixture.h - one core node with a scripted bus
 * for the NMT / heartbeat / guarding / EMCY tests.
 *
 * Every frame the node sends is logged; frames are fed in with ecf_rx()
 * (any length, RTR, 11-bit). The fixture owns the clock: ecf_advance()
 * steps to each deadline of the node in turn (ticking exactly there), so
 * "lost at T, not before" can be asserted to the microsecond.
 * No bus: the test is the node's only peer. Nodes that talk to each other
 * share the in-memory bus of test_bus.h (ecf_od_std() gives them this
 * fixture's dictionary).
 */
#ifndef COGW_TESTS_ERRCTRL_FIXTURE_H
#define COGW_TESTS_ERRCTRL_FIXTURE_H

#include <stdint.h>

#include "core/co.h"
#include "tests/unit/support/test_bus.h"

#define ECF_LOG 512

typedef struct ecf {
	co_od *od;
	co_node *node;
	uint64_t now;
	co_frame tx[ECF_LOG];
	uint64_t tx_t[ECF_LOG];
	unsigned n_tx;
	evlog ev; /* the node's events */
} ecf;

/* OD with 1000h, 1001h, 1003h(8), 1014h, 1015h, 1016h(4), 1017h,
 * 1028h(4, valid), 1029h(2), 102Ah, 100Ch, 100Dh. */
co_od *ecf_od_std(uint8_t node_id);
/* Create the node on `od` (NULL = ecf_od_std) at time 0; no tick yet. */
void ecf_create(ecf *x, uint8_t node_id, co_od *od);
/* Create + first tick at 0 (boot-up sent), logs cleared. */
void ecf_boot(ecf *x, uint8_t node_id);
void ecf_destroy(ecf *x);

void ecf_rx(ecf *x, uint32_t id, uint8_t flags, uint8_t len, const uint8_t *data);
void ecf_rx1(ecf *x, uint32_t id, uint8_t byte);
/* Step the clock to t, ticking at every deadline on the way. */
void ecf_advance(ecf *x, uint64_t t);
void ecf_clear(ecf *x);

int ecf_tx_find(const ecf *x, unsigned from, uint32_t id);
/* The last frame the node sent with this id, NULL if none. */
const co_frame *ecf_tx_last(const ecf *x, uint32_t id);
/* An SDO request to the node's default server channel (600h + its id). */
void ecf_sdo_req(ecf *x, const uint8_t req[8]);
unsigned ecf_tx_count(const ecf *x, uint32_t id);
int ecf_ev_find(const ecf *x, unsigned from, co_event_kind kind);
unsigned ecf_ev_count(const ecf *x, co_event_kind kind);

#endif
