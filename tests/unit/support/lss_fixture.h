/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/support/lss_fixture.h - a core node with an OD holding
 * 1018h:1..4, on a membus, recording its events. Used by the LSS tests.
 */
#ifndef COGW_TESTS_LSS_FIXTURE_H
#define COGW_TESTS_LSS_FIXTURE_H

#include "core/co.h"
#include "core/lss.h"
#include "tests/unit/support/membus.h"

typedef struct lss_fixture {
	co_od *od;
	co_node *node;
	evlog ev;
} lss_fixture;

/* cfg: template (od, send, event are filled in); id: 1018h:1..4 values,
 * NULL for none. Returns co_node_create()'s result. */
int lss_fixture_create(lss_fixture *t, membus *bus, const co_node_config *cfg,
		       const lss_address *id);
void lss_fixture_destroy(lss_fixture *t);

/* The n-th (0-based) logged frame with COB-ID id must carry these 8
 * bytes. Other services' frames (boot-up, heartbeat) are skipped. */
void lss_fixture_expect_frame(const membus *bus, unsigned n, uint32_t id, const uint8_t want[8]);

#endif
