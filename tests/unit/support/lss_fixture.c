/* SPDX-License-Identifier: MIT */
#include "tests/unit/support/lss_fixture.h"

#include <stdio.h>
#include <string.h>

#include "unity.h"

int lss_fixture_create(lss_fixture *t, membus *bus, const co_node_config *tmpl,
		       const lss_address *id)
{
	co_node_config cfg = *tmpl;
	int rc;

	memset(t, 0, sizeof(*t));
	rc = co_od_create(&t->od, 16);
	if (rc)
		return rc;
	if (id) {
		co_od_add_num(t->od, 0x1018, 0, CO_T_UNSIGNED8, CO_ACC_CO, 4, NULL);
		for (uint8_t s = 1; s <= 4; s++)
			co_od_add_num(t->od, 0x1018, s, CO_T_UNSIGNED32, CO_ACC_CO, id->id[s - 1],
				      NULL);
	}
	cfg.od = t->od;
	cfg.send = membus_send;
	cfg.send_ctx = membus_port_new(bus);
	cfg.event = evlog_fn;
	cfg.event_ctx = &t->ev;
	rc = co_node_create(&t->node, &cfg);
	if (rc)
		return rc;
	membus_bind(bus, t->node);
	return 0;
}

void lss_fixture_destroy(lss_fixture *t)
{
	co_node_destroy(t->node);
	co_od_destroy(t->od);
	t->node = NULL;
	t->od = NULL;
}

void lss_fixture_expect_frame(const membus *bus, unsigned n, uint32_t id, const uint8_t want[8])
{
	char msg[48];
	int i = membus_log_nth(bus, id, n);

	snprintf(msg, sizeof(msg), "frame #%u on %03X", n, (unsigned)id);
	TEST_ASSERT_TRUE_MESSAGE(i >= 0, msg);
	TEST_ASSERT_EQUAL_UINT8_MESSAGE(8, bus->log[i].f.len, msg);
	TEST_ASSERT_EQUAL_HEX8_ARRAY_MESSAGE(want, bus->log[i].f.data, 8, msg);
}
