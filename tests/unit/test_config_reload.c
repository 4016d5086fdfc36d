/* SPDX-License-Identifier: MIT */
/*
 * What a reload changes at run time and what it refuses
 * (apps/common/config_reload.c, docs/config.md "Reload"): the node diff of
 * a line with a manager (added, changed, removed, by node-ID, removals
 * first), the keys that need a restart named by their JSON path (a node's
 * program, a concise DCF beyond the room of its 1F22h:n, a node list
 * without a manager, the line's bit rate), and the explicit heartbeat
 * consumers told apart from the nodes' own 1016h entries.
 */
#include <stdio.h>
#include <string.h>

#include "apps/common/config.h"
#include "unity.h"

static cogw_config cur, next;
static cogw_node_diff nd;
static char err[512], what[2048];

void setUp(void)
{
	memset(&cur, 0, sizeof cur);
	memset(&next, 0, sizeof next);
	memset(&nd, 0, sizeof nd);
	err[0] = what[0] = '\0';
}

void tearDown(void)
{
	cogw_config_free(&cur);
	cogw_config_free(&next);
}

#define LINE(bitrate, extra)                                                                       \
	"{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": " bitrate ", \"node_id\": 127" extra \
	"}]}"
#define MGR ", \"manager\": {}"

static void load(cogw_config *c, const char *json)
{
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, cogw_config_load_string(c, json, "t", err, sizeof err),
				      err);
}

/* cur -> next on line 0: the diff's result, nd filled. */
static bool diff(void)
{
	const cogw_node *in_force[128];
	cogw_nodes_by_id(&cur.lines[0], in_force);
	return cogw_config_node_diff(in_force, &cur.lines[0], &next.lines[0], 0, &nd);
}

static void test_nodes_added_changed_removed_by_id(void)
{
	load(&cur, LINE("500000", MGR ", \"nodes\": [{\"id\": 3}, {\"id\": 5, \"heartbeat_ms\": "
				      "500}, {\"id\": 9}]"));
	/* 3 unchanged (moved in the array), 5 changed, 9 removed, 7 added */
	load(&next, LINE("500000", MGR ", \"nodes\": [{\"id\": 7, \"mandatory\": true}, {\"id\": "
				       "5, \"heartbeat_ms\": 800}, {\"id\": 3}]"));
	TEST_ASSERT_TRUE(cogw_config_reload_check(&cur, &next, what, sizeof what));
	TEST_ASSERT_EQUAL_STRING("", what);
	TEST_ASSERT_TRUE_MESSAGE(diff(), nd.what);
	TEST_ASSERT_EQUAL_size_t(3, nd.n);
	/* the removal first: the 1016h entry it frees may serve an addition */
	TEST_ASSERT_EQUAL_UINT8(COGW_NODE_REMOVED, nd.change[0].kind);
	TEST_ASSERT_EQUAL_UINT8(9, nd.change[0].id);
	TEST_ASSERT_EQUAL_UINT8(COGW_NODE_ADDED, nd.change[1].kind);
	TEST_ASSERT_EQUAL_UINT8(7, nd.change[1].id);
	TEST_ASSERT_EQUAL_size_t(0, nd.change[1].index);
	TEST_ASSERT_TRUE(nd.change[1].node->assignment & 0x08u); /* mandatory */
	TEST_ASSERT_EQUAL_UINT8(COGW_NODE_CHANGED, nd.change[2].kind);
	TEST_ASSERT_EQUAL_UINT8(5, nd.change[2].id);
	TEST_ASSERT_EQUAL_size_t(1, nd.change[2].index);
	TEST_ASSERT_EQUAL_UINT16(800, nd.change[2].node->heartbeat_ms);
}

static void test_same_nodes_no_change(void)
{
	const char *json = LINE("500000", MGR ", \"nodes\": [{\"id\": 3, \"config\": {\"entries\": "
					      "[{\"index\": \"0x1017\", \"type\": \"UNSIGNED16\", "
					      "\"value\": 500}]}}]");
	load(&cur, json);
	load(&next, json);
	TEST_ASSERT_TRUE(diff());
	TEST_ASSERT_EQUAL_size_t(0, nd.n);
	TEST_ASSERT_EQUAL_STRING("", nd.what);
}

/* Each key of a node entry the line follows is a change of that node. */
static void test_every_live_node_key_is_a_change(void)
{
	static const char *const variants[] = {
		"\"mandatory\": true",
		"\"boot\": false",
		"\"keep_alive\": true",
		"\"guard_time_ms\": 100, \"retry_factor\": 3",
		"\"heartbeat_ms\": 250",
		"\"vendor_id\": \"0x1234\"",
		"\"serial\": 7",
		"\"keep_op\": true",
		"\"state\": \"pre-operational\"",
		"\"pdo\": \"auto\"",
		"\"config\": {\"entries\": [{\"index\": \"0x1017\", \"type\": \"UNSIGNED16\", "
		"\"value\": 100}]}",
	};
	char json[512];

	for (size_t i = 0; i < sizeof variants / sizeof variants[0]; i++) {
		tearDown();
		setUp();
		load(&cur, LINE("500000", MGR ", \"nodes\": [{\"id\": 4}]"));
		snprintf(json, sizeof json, LINE("500000", MGR ", \"nodes\": [{\"id\": 4, %s}]"),
			 variants[i]);
		load(&next, json);
		TEST_ASSERT_TRUE_MESSAGE(cogw_config_reload_check(&cur, &next, what, sizeof what),
					 what);
		TEST_ASSERT_TRUE_MESSAGE(diff(), variants[i]);
		TEST_ASSERT_EQUAL_size_t_MESSAGE(1, nd.n, variants[i]);
		TEST_ASSERT_EQUAL_UINT8_MESSAGE(COGW_NODE_CHANGED, nd.change[0].kind, variants[i]);
	}
}

/* What a node needs a restart for is named by its JSON path. */
static void test_software_needs_a_restart(void)
{
	load(&cur, LINE("500000", MGR ", \"nodes\": [{\"id\": 4}, {\"id\": 6}]"));
	load(&next, LINE("500000", MGR ", \"nodes\": [{\"id\": 4}, {\"id\": 6, \"software_id\": "
				       "\"0x10\"}]"));
	TEST_ASSERT_FALSE(diff());
	TEST_ASSERT_EQUAL_STRING("lines[0].nodes[1].software_id: needs a restart", nd.what);
}

/* A node not in the file at start-up got 1F22h:n with 4 KiB of room. */
static void test_concise_dcf_beyond_its_room(void)
{
	static char json[96 * 1024];
	size_t off;

	load(&cur, LINE("500000", MGR));
	off = (size_t)snprintf(json, sizeof json,
			       "{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, "
			       "\"node_id\": 127, \"manager\": {}, \"nodes\": [{\"id\": 8, "
			       "\"config\": {\"entries\": [");
	for (int i = 0; i < 500; i++)
		off += (size_t)snprintf(json + off, sizeof json - off,
					"%s{\"index\": \"0x2000\", \"sub\": %d, \"type\": "
					"\"UNSIGNED32\", \"value\": %d}",
					i ? ", " : "", i % 255, i);
	snprintf(json + off, sizeof json - off, "]}}]}]}");
	load(&next, json);
	TEST_ASSERT_TRUE(next.lines[0].nodes[0].config.cdcf_len > 4096);
	TEST_ASSERT_FALSE(diff());
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(nd.what, "lines[0].nodes[0].config (a concise DCF of "),
				     nd.what);
	TEST_ASSERT_NOT_NULL(strstr(nd.what, "1F22h:8 holds 4096): needs a restart"));
	TEST_ASSERT_EQUAL_UINT32(4096, cogw_node_cdcf_room(&cur.lines[0], 8));
	TEST_ASSERT_EQUAL_UINT32(0, cogw_node_cdcf_room(&cur.lines[0], 127)); /* our own */
}

static void test_nodes_without_a_manager_need_a_restart(void)
{
	load(&cur, LINE("500000", ", \"nodes\": [{\"id\": 4}]"));
	load(&next, LINE("500000", ", \"nodes\": [{\"id\": 4}, {\"id\": 5}]"));
	TEST_ASSERT_FALSE(diff());
	TEST_ASSERT_EQUAL_STRING("lines[0].nodes: needs a restart", nd.what);
}

/* Restart-only keys by path; rt, heartbeat_ms and consumers are live. */
static void test_restart_keys_by_path(void)
{
	load(&cur, LINE("500000", MGR ", \"nodes\": [{\"id\": 4}]"));
	load(&next, LINE("250000", ", \"manager\": {\"retry_ms\": 500}, \"nodes\": [{\"id\": 4}]"));
	TEST_ASSERT_FALSE(cogw_config_reload_check(&cur, &next, what, sizeof what));
	TEST_ASSERT_EQUAL_STRING("lines[0].bitrate: needs a restart; lines[0].manager: needs a "
				 "restart",
				 what);
	cogw_config_free(&next);
	memset(&next, 0, sizeof next);
	load(&next, LINE("500000", MGR ", \"heartbeat_ms\": 200, \"rt\": {\"priority\": 10}, "
				       "\"heartbeat_consumers\": [{\"node_id\": 20, \"time_ms\": "
				       "900}], \"nodes\": [{\"id\": 4}]"));
	TEST_ASSERT_TRUE_MESSAGE(cogw_config_reload_check(&cur, &next, what, sizeof what), what);
}

/* The explicit consumers, without the 1016h entries of the nodes. */
static void test_consumers_apart_from_nodes(void)
{
	uint16_t ms[128];

	load(&cur, LINE("500000", MGR ", \"heartbeat_consumers\": [{\"node_id\": 20, \"time_ms\": "
				      "900}], \"nodes\": [{\"id\": 4, \"heartbeat_ms\": 300}]"));
	TEST_ASSERT_EQUAL_size_t(2, cur.lines[0].n_hb_consumers); /* 1016h holds both */
	TEST_ASSERT_EQUAL_size_t(1, cogw_config_consumers(&cur.lines[0], ms));
	TEST_ASSERT_EQUAL_UINT16(900, ms[20]);
	TEST_ASSERT_EQUAL_UINT16(0, ms[4]);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_nodes_added_changed_removed_by_id);
	RUN_TEST(test_same_nodes_no_change);
	RUN_TEST(test_every_live_node_key_is_a_change);
	RUN_TEST(test_software_needs_a_restart);
	RUN_TEST(test_concise_dcf_beyond_its_room);
	RUN_TEST(test_nodes_without_a_manager_need_a_restart);
	RUN_TEST(test_restart_keys_by_path);
	RUN_TEST(test_consumers_apart_from_nodes);
	return UNITY_END();
}
