/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/support/lss_fixture.h - a core node with an OD holding
 * 1018h:1..4, on the in-memory bus (test_bus.h), recording its events.
 * Used by the LSS tests, whose clock starts at 0.
 */
#ifndef COGW_TESTS_LSS_FIXTURE_H
#define COGW_TESTS_LSS_FIXTURE_H

#include "core/co.h"
#include "core/lss.h"
#include "tests/unit/support/test_bus.h"

typedef struct lss_fixture {
	co_od *od; /* both owned by the bus: tb_fini() destroys them */
	co_node *node;
	evlog ev;
} lss_fixture;

/* A bus whose clock starts at 0. */
void lss_bus_init(tb_bus *bus);

/* cfg: template (od, send, event are filled in); id: 1018h:1..4 values,
 * NULL for none. Returns 0, or -1 when the node cannot be made. */
int lss_fixture_create(lss_fixture *t, tb_bus *bus, const co_node_config *cfg,
		       const lss_address *id);

/* A scripted node puts this 8-byte frame on the bus; it is delivered. */
void lss_bus_inject(tb_bus *bus, uint32_t id, const uint8_t data[8]);

/* The n-th (0-based) logged frame with COB-ID id must carry these 8
 * bytes. Other services' frames (boot-up, heartbeat) are skipped. */
void lss_fixture_expect_frame(const tb_bus *bus, unsigned n, uint32_t id, const uint8_t want[8]);

#endif
