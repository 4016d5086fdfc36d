/* SPDX-License-Identifier: MIT */
#include "tests/unit/support/lss_fixture.h"

#include <stdio.h>
#include <string.h>

#include "unity.h"

void lss_bus_init(tb_bus *bus)
{
	tb_init(bus);
	bus->now = 0;
}

int lss_fixture_create(lss_fixture *t, tb_bus *bus, const co_node_config *tmpl,
		       const lss_address *id)
{
	co_node_config cfg = *tmpl;
	co_od *od;
	tb_port *p;

	memset(t, 0, sizeof(*t));
	if (co_od_create(&od, 16))
		return -1;
	if (id) {
		co_od_add_num(od, 0x1018, 0, CO_T_UNSIGNED8, CO_ACC_CO, 4, NULL);
		for (uint8_t s = 1; s <= 4; s++)
			co_od_add_num(od, 0x1018, s, CO_T_UNSIGNED32, CO_ACC_CO, id->id[s - 1],
				      NULL);
	}
	p = tb_add_node(bus, &cfg, od);
	if (!p)
		return -1;
	/* what the node reported while it was made, then everything after */
	for (size_t i = 0; i < p->n_ev; i++)
		evlog_fn(&t->ev, &p->ev[i]);
	p->ext_event = evlog_fn;
	p->ext_ctx = &t->ev;
	t->od = od;
	t->node = p->node;
	return 0;
}

void lss_bus_inject(tb_bus *bus, uint32_t id, const uint8_t data[8])
{
	co_frame f;

	co_frame_init(&f, id, 8);
	memcpy(f.data, data, 8);
	tb_send(bus, &f);
}

void lss_fixture_expect_frame(const tb_bus *bus, unsigned n, uint32_t id, const uint8_t want[8])
{
	char msg[48];
	int i = tb_log_nth_id(bus, id, n);

	snprintf(msg, sizeof(msg), "frame #%u on %03X", n, (unsigned)id);
	TEST_ASSERT_TRUE_MESSAGE(i >= 0, msg);
	TEST_ASSERT_EQUAL_UINT8_MESSAGE(8, tb_log_at(bus, (size_t)i)->len, msg);
	TEST_ASSERT_EQUAL_HEX8_ARRAY_MESSAGE(want, tb_log_at(bus, (size_t)i)->data, 8, msg);
}
