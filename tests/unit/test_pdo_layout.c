/* SPDX-License-Identifier: MIT */
/*
 * core/pdo_layout: room only for the nodes asked for, PDOs beyond the room
 * counted as dropped, offsets and frame length computed from the mapping
 * (CiA 301 §7.4.7.1: LSB first), valid/generation through begin, commit
 * and invalidate, lookups by object, the type list and the text form.
 */
#include <errno.h>
#include <string.h>

#include "core/od.h"
#include "core/pdo_layout.h"
#include "unity.h"

static co_pdo_layout *t;

void setUp(void)
{
	const uint32_t nodes[4] = { 1u << 5 | 1u << 9, 0, 0, 1u << 31 }; /* 5, 9, 127 */
	TEST_ASSERT_EQUAL_INT(0, co_pdo_layout_create(&t, nodes, 2));
}

void tearDown(void)
{
	co_pdo_layout_destroy(t);
	t = NULL;
}

static co_pdo_layout_pdo pdo2(uint16_t nr, uint32_t cob)
{
	co_pdo_layout_pdo p = { .nr = nr, .cob = cob, .tt = 254, .n = 2 };
	p.map[0] = (co_pdo_layout_entry){ .index = 0x6000, .sub = 1, .bits = 8 };
	p.map[1] = (co_pdo_layout_entry){
		.index = 0x6401, .sub = 1, .bits = 16, .type = CO_T_INTEGER16
	};
	return p;
}

static void test_room_only_for_the_nodes_asked_for(void)
{
	const uint32_t none[4] = { 0 };
	co_pdo_layout *empty = NULL;

	TEST_ASSERT_NOT_NULL(co_pdo_layout_node_get(t, 5));
	TEST_ASSERT_NOT_NULL(co_pdo_layout_node_get(t, 127));
	TEST_ASSERT_NULL(co_pdo_layout_node_get(t, 6));
	TEST_ASSERT_NULL(co_pdo_layout_node_get(t, 0));
	TEST_ASSERT_NULL(co_pdo_layout_node_get(t, 128));
	TEST_ASSERT_EQUAL_INT(-ENOENT, co_pdo_layout_begin(t, 6, CO_PDO_LAYOUT_SCAN));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_pdo_layout_create(&empty, none, 0));
	TEST_ASSERT_EQUAL_INT(-EINVAL, co_pdo_layout_create(&empty, none, CO_PDO_MAX + 1));
	TEST_ASSERT_EQUAL_INT(0, co_pdo_layout_create(&empty, none, 8));
	TEST_ASSERT_NULL(co_pdo_layout_node_get(empty, 5));
	co_pdo_layout_destroy(empty);
	co_pdo_layout_destroy(NULL);
}

static void test_learn_drop_find_invalidate(void)
{
	co_pdo_layout_pdo p = pdo2(1, 0x185);
	const co_pdo_layout_pdo *found;
	uint8_t pos;

	TEST_ASSERT_EQUAL_INT(0, co_pdo_layout_begin(t, 5, CO_PDO_LAYOUT_SCAN));
	const co_pdo_layout_node *n = co_pdo_layout_node_get(t, 5);
	uint32_t gen = n->generation;
	const co_pdo_layout_pdo *kept = co_pdo_layout_add(t, 5, CO_PDO_TX, &p);
	TEST_ASSERT_NOT_NULL(kept);
	TEST_ASSERT_EQUAL_UINT8(0, kept->map[0].offset);
	TEST_ASSERT_EQUAL_UINT8(8, kept->map[1].offset);
	TEST_ASSERT_EQUAL_UINT8(3, kept->bytes);
	p.nr = 2;
	TEST_ASSERT_NOT_NULL(co_pdo_layout_add(t, 5, CO_PDO_TX, &p));
	p.nr = 3;
	TEST_ASSERT_NULL(co_pdo_layout_add(t, 5, CO_PDO_TX, &p)); /* room for 2 */
	TEST_ASSERT_EQUAL_UINT16(1, n->dropped[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_UINT16(2, n->n[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_UINT16(0, n->n[CO_PDO_RX]);
	/* not valid until committed */
	TEST_ASSERT_FALSE(co_pdo_layout_find(t, 5, CO_PDO_TX, 0x6401, 1, &found, &pos));
	co_pdo_layout_commit(t, 5, 1234);
	TEST_ASSERT_TRUE(n->valid);
	TEST_ASSERT_EQUAL_UINT64(1234, n->learned_us);
	TEST_ASSERT_EQUAL_UINT32(gen + 1, n->generation);
	TEST_ASSERT_TRUE(co_pdo_layout_find(t, 5, CO_PDO_TX, 0x6401, 1, &found, &pos));
	TEST_ASSERT_EQUAL_UINT16(1, found->nr);
	TEST_ASSERT_EQUAL_UINT8(1, pos);
	TEST_ASSERT_FALSE(co_pdo_layout_find(t, 5, CO_PDO_RX, 0x6401, 1, &found, &pos));
	/* a boot-up: invalid, content kept for display, once */
	co_pdo_layout_invalidate(t, 5);
	co_pdo_layout_invalidate(t, 5);
	TEST_ASSERT_FALSE(n->valid);
	TEST_ASSERT_EQUAL_UINT32(gen + 2, n->generation);
	TEST_ASSERT_EQUAL_UINT16(2, n->n[CO_PDO_TX]);
	TEST_ASSERT_FALSE(co_pdo_layout_find(t, 5, CO_PDO_TX, 0x6401, 1, &found, &pos));
	/* learning again starts empty */
	TEST_ASSERT_EQUAL_INT(0, co_pdo_layout_begin(t, 5, CO_PDO_LAYOUT_FILE));
	TEST_ASSERT_EQUAL_UINT16(0, n->n[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_UINT16(0, n->dropped[CO_PDO_TX]);
	TEST_ASSERT_EQUAL_STRING("file", co_pdo_layout_source_to_string(n->source));
}

static void test_type_list_and_text(void)
{
	const co_pdo_layout_type list[] = { { 0x2000, 0, CO_ACC_RO, CO_T_REAL32 },
					    { 0x6000, 1, CO_ACC_RO, CO_T_UNSIGNED8 },
					    { 0x6401, 1, 0, CO_T_INTEGER16 },
					    { 0x6401, 2, 0, CO_T_INTEGER16 } };
	char text[200];
	co_pdo_layout_pdo p = pdo2(4, 0x485);

	TEST_ASSERT_EQUAL_PTR(&list[2], co_pdo_layout_type_find(list, 4, 0x6401, 1));
	TEST_ASSERT_EQUAL_PTR(&list[0], co_pdo_layout_type_find(list, 4, 0x2000, 0));
	TEST_ASSERT_NULL(co_pdo_layout_type_find(list, 4, 0x6401, 3));
	TEST_ASSERT_NULL(co_pdo_layout_type_find(NULL, 0, 0x6401, 1));
	co_pdo_layout_pdo_format(text, sizeof text, CO_PDO_TX, &p);
	TEST_ASSERT_EQUAL_STRING("TPDO 4 COB-ID 485h tt 254 inhibit 0 event 0 ms: 6000:01/8 "
				 "(type unknown), 6401:01/16 INTEGER16",
				 text);
	p.n = 1;
	p.map[0] = (co_pdo_layout_entry){ .index = 0x0005, .bits = 8, .type = CO_T_UNSIGNED8 };
	co_pdo_layout_pdo_format(text, sizeof text, CO_PDO_RX, &p);
	TEST_ASSERT_EQUAL_STRING(
		"RPDO 4 COB-ID 485h tt 254 inhibit 0 event 0 ms: 0005:00/8 (dummy)", text);
	p.n = 0;
	co_pdo_layout_pdo_format(text, 20, CO_PDO_RX, &p); /* cut, terminated */
	TEST_ASSERT_EQUAL_size_t(19, strlen(text));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_room_only_for_the_nodes_asked_for);
	RUN_TEST(test_learn_drop_find_invalidate);
	RUN_TEST(test_type_list_and_text);
	return UNITY_END();
}
