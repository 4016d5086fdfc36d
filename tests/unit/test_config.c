/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_config.c - cogwd's JSON configuration: every class of bad
 * input gets its exact "source: path: reason" message; the embedded default
 * parses; the ODs hold what the JSON says, typed, with limits that
 * co_od_write enforces afterwards; the reload check.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "unity.h"

#include "apps/common/config.h"
#include "apps/common/json_od.h"
#include "core/od.h"
#include "core/sdo.h"
#include "mailbox/proto.h"

static cogw_config cfg;
static char err[512];

void setUp(void)
{
	memset(&cfg, 0, sizeof(cfg));
	err[0] = '\0';
}

void tearDown(void)
{
	cogw_config_free(&cfg);
}

/* One line around the given extra line keys. */
#define LINE(extra) "{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 5" extra "}"
#define CFG1(extra) "{\"lines\": [" LINE(extra) "]}"

static void expect_error(const char *json, const char *msg)
{
	int rc = cogw_config_load_string(&cfg, json, "t.json", err, sizeof(err));

	TEST_ASSERT_EQUAL_INT(-EINVAL, rc);
	TEST_ASSERT_EQUAL_STRING(msg, err);
	/* A failed load leaves nothing behind to free or to use. */
	TEST_ASSERT_EQUAL_size_t(0, cfg.n_lines);
	TEST_ASSERT_NULL(cfg.lines[0].od);
}

static void load_ok(const char *json)
{
	int rc = cogw_config_load_string(&cfg, json, "t.json", err, sizeof(err));

	TEST_ASSERT_EQUAL_STRING("", err);
	TEST_ASSERT_EQUAL_INT(0, rc);
}

/* The embedded default, as cogwd loads it (its DCF compiled in with it). */
static void load_default(void)
{
	int rc = cogw_config_load_string(&cfg, cogw_default_config_json, COGW_DEFAULT_CONFIG_SOURCE,
					 err, sizeof(err));

	TEST_ASSERT_EQUAL_STRING("", err);
	TEST_ASSERT_EQUAL_INT(0, rc);
}

static uint64_t raw(const co_od *od, uint16_t index, uint8_t sub)
{
	co_od_entry *e = co_od_find(od, index, sub);

	TEST_ASSERT_NOT_NULL_MESSAGE(e, "entry missing");
	return co_od_entry_raw(e);
}

/* ---- the embedded default -------------------------------------------------- */

static void test_embedded_default_parses(void)
{
	co_od *od;
	char name[80];
	uint32_t len;

	load_default();
	TEST_ASSERT_EQUAL_size_t(3, cfg.n_lines);
	TEST_ASSERT_EQUAL_STRING("/var/lib/cogw", cfg.state_dir);
	TEST_ASSERT_EQUAL_STRING("main", cfg.mailbox.instance);
	TEST_ASSERT_EQUAL_UINT(0620, cfg.mailbox.queue_mode);
	TEST_ASSERT_EQUAL_UINT(COGW_ACCESS_WRITE, cfg.mailbox.default_access);
	for (size_t i = 0; i < 3; i++) {
		char ifn[16];

		snprintf(ifn, sizeof(ifn), "vcan%zu", i);
		TEST_ASSERT_EQUAL_STRING(ifn, cfg.lines[i].interface);
		TEST_ASSERT_EQUAL_UINT32(1000000, cfg.lines[i].bitrate);
		TEST_ASSERT_EQUAL_UINT8(127, cfg.lines[i].node_id);
		TEST_ASSERT_EQUAL_UINT16(i + 1, cfg.lines[i].network_id);
		TEST_ASSERT_EQUAL_UINT16(1000, cfg.lines[i].heartbeat_ms);
		TEST_ASSERT_EQUAL_INT(-1, cfg.lines[i].rt.cpu);
		TEST_ASSERT_NOT_NULL(cfg.lines[i].od);
	}
	TEST_ASSERT_EQUAL_size_t(1, cfg.lines[0].n_hb_consumers);
	TEST_ASSERT_EQUAL_UINT8(1, cfg.lines[0].hb_consumers[0].node_id);
	TEST_ASSERT_EQUAL_UINT16(1500, cfg.lines[0].hb_consumers[0].time_ms);
	TEST_ASSERT_EQUAL_UINT8(2, cfg.lines[1].hb_consumers[0].node_id);
	TEST_ASSERT_EQUAL_size_t(0, cfg.lines[2].n_hb_consumers);

	od = cfg.lines[0].od;
	TEST_ASSERT_EQUAL_HEX64(0x000105DC, raw(od, 0x1016, 1)); /* node 1, 1500 */
	TEST_ASSERT_EQUAL_HEX64(0, raw(od, 0x1016, 2));
	TEST_ASSERT_EQUAL_HEX64(127, raw(od, 0x1016, 0));
	TEST_ASSERT_EQUAL_HEX64(1000, raw(od, 0x1017, 0));
	TEST_ASSERT_EQUAL_HEX64(0x67F, raw(od, 0x1200, 1));
	TEST_ASSERT_EQUAL_HEX64(0x5FF, raw(od, 0x1200, 2));
	TEST_ASSERT_EQUAL_HEX64(4, raw(od, 0x1018, 0));
	TEST_ASSERT_EQUAL_HEX64(0x80, raw(od, 0x1005, 0)); /* no SYNC producer */
	TEST_ASSERT_EQUAL_HEX64(0xFF, raw(od, 0x1014, 0));
	/* Four SDO clients by default, not valid until used. */
	TEST_ASSERT_EQUAL_HEX64(0x80000000u, raw(od, 0x1283, 1));
	TEST_ASSERT_NULL(co_od_find(od, 0x1284, 0));
	TEST_ASSERT_EQUAL_HEX64(127, raw(od, 0x1F2C, 0));
	TEST_ASSERT_EQUAL_INT(0, co_od_get_bytes(od, 0x1008, 0, name, sizeof(name), &len));
	TEST_ASSERT_EQUAL_UINT32(12, len);
	TEST_ASSERT_EQUAL_MEMORY("cogw gateway", name, 12);
	TEST_ASSERT_EQUAL_HEX16(CO_ACC_CO, co_od_find(od, 0x1008, 0)->access);
}

/* A bare cogwd started outside the source tree: the embedded default needs
 * nothing from the working directory, its node configuration included. */
static void test_embedded_default_loads_from_any_directory(void)
{
	char here[4096];
	char tmp[] = "/tmp/cogw-cfg-XXXXXX";
	const cogw_node_config *nc = NULL;

	TEST_ASSERT_NOT_NULL(getcwd(here, sizeof(here)));
	TEST_ASSERT_NOT_NULL(mkdtemp(tmp));
	TEST_ASSERT_EQUAL_INT(0, chdir(tmp));
	int rc = cogw_config_load_string(&cfg, cogw_default_config_json, COGW_DEFAULT_CONFIG_SOURCE,
					 err, sizeof(err));
	TEST_ASSERT_EQUAL_INT(0, chdir(here));
	TEST_ASSERT_EQUAL_INT(0, rmdir(tmp));
	TEST_ASSERT_EQUAL_STRING("", err);
	TEST_ASSERT_EQUAL_INT(0, rc);
	for (size_t i = 0; i < cfg.lines[0].n_nodes; i++) /* the demo transducer */
		if (cfg.lines[0].nodes[i].config.source == COGW_NODE_CONFIG_DCF)
			nc = &cfg.lines[0].nodes[i].config;
	TEST_ASSERT_NOT_NULL_MESSAGE(nc, "the default's transducer has no DCF configuration");
	TEST_ASSERT_TRUE(nc->entries > 0);
	TEST_ASSERT_NOT_NULL(nc->cdcf);
}

static void test_defaults_of_optional_keys(void)
{
	load_ok(CFG1(""));
	TEST_ASSERT_EQUAL_STRING("line0", cfg.lines[0].name);
	TEST_ASSERT_EQUAL_UINT16(1, cfg.lines[0].network_id);
	TEST_ASSERT_EQUAL_UINT8(1, cfg.lines[0].sdo_servers);
	TEST_ASSERT_EQUAL_UINT8(4, cfg.lines[0].sdo_clients);
	TEST_ASSERT_EQUAL_UINT32(1000, cfg.lines[0].sdo_timeout_ms);
	TEST_ASSERT_EQUAL_UINT32(128, cfg.lines[0].sdo_block_threshold);
	TEST_ASSERT_EQUAL_UINT32(500, cfg.watchdog_check_ms);
	TEST_ASSERT_EQUAL_UINT(64, cfg.mailbox.depth);
	TEST_ASSERT_EQUAL_UINT(1024, cfg.mailbox.msg_size);
	TEST_ASSERT_EQUAL_UINT(1u << 20, cfg.mailbox.max_transfer);
	TEST_ASSERT_EQUAL_STRING("t.json", cfg.source);
}

/* ---- one test per class of bad input ----------------------------------------- */

static void test_invalid_json_line_column(void)
{
	expect_error("{\n  \"lines\": [\n    { \"interface\": \"vcan0\",, }\n  ]\n}",
		     "t.json: line 3 column 29: invalid JSON");
	expect_error("", "t.json: line 1 column 1: invalid JSON");
	/* Trailing garbage is not ignored. */
	expect_error("{\"lines\": []} x", "t.json: line 1 column 15: invalid JSON");
}

static void test_wrong_types(void)
{
	expect_error(CFG1(", \"heartbeat_ms\": \"fast\""),
		     "t.json: lines[0].heartbeat_ms: \"fast\" is not an integer");
	expect_error(CFG1(", \"heartbeat_ms\": true"),
		     "t.json: lines[0].heartbeat_ms: expected an integer, got a boolean");
	expect_error(CFG1(", \"heartbeat_ms\": 1.5"),
		     "t.json: lines[0].heartbeat_ms: 1.5 is not an integer");
	expect_error("{\"mlockall\": 1, \"lines\": [" LINE("") "]}",
		     "t.json: mlockall: expected true or false, got a number");
	expect_error("{\"lines\": {}}", "t.json: lines: expected a non-empty array, got an object");
	expect_error("[]", "t.json: (top): expected an object, got an array");
	expect_error("{\"mailbox\": {\"queue_mode\": 432}, \"lines\": [" LINE("") "]}",
		     "t.json: mailbox.queue_mode: expected an octal string like \"0620\"");
	/* A command queue clients can read leaks their tokens */
	static const char *const readable[] = { "0660", "0666", "0640", "0604", "0777" };
	for (size_t i = 0; i < sizeof readable / sizeof readable[0]; i++) {
		char json[256];

		snprintf(json, sizeof json,
			 "{\"mailbox\": {\"queue_mode\": \"%s\"}, \"lines\": [" LINE("") "]}",
			 readable[i]);
		expect_error(json, "t.json: mailbox.queue_mode: clients could "
				   "read other clients' tokens: no read bit for "
				   "group or others (e.g. \"0620\" or \"0622\")");
	}
}

/* Every mailbox limit is a key with a range, and the limits that
 * depend on each other are refused together, each with its JSON path. */
static void test_mailbox_limits_refused_with_path(void)
{
	static const struct {
		const char *mailbox, *error;
	} bad[] = {
		{ "\"max_clients_per_uid\": 0",
		  "mailbox.max_clients_per_uid: 0 is out of range 1..1024" },
		{ "\"max_clients\": 8, \"max_clients_per_uid\": 9",
		  "mailbox.max_clients_per_uid: 9 is more than max_clients (8)" },
		{ "\"max_outstanding\": 0", "mailbox.max_outstanding: 0 is out of range 1..1024" },
		{ "\"max_outstanding\": 1025",
		  "mailbox.max_outstanding: 1025 is out of range 1..1024" },
		{ "\"max_read_outstanding\": 0",
		  "mailbox.max_read_outstanding: 0 is out of range 1..65535" },
		{ "\"write_reserve\": 0", "mailbox.write_reserve: 0 is out of range 1..1023" },
		{ "\"max_clients\": 4, \"write_reserve\": 4",
		  "mailbox.write_reserve: 4 leaves read-only clients no slot (max_clients is 4)" },
		{ "\"max_request_timeout_ms\": 0",
		  "mailbox.max_request_timeout_ms: 0 is out of range 1..3600000" },
		{ "\"max_request_timeout_ms\": 4294967295",
		  "mailbox.max_request_timeout_ms: 4294967295 is out of range 1..3600000" },
		{ "\"transfer_slots\": 0", "mailbox.transfer_slots: 0 is out of range 1..255" },
		{ "\"transfer_slots\": 256", "mailbox.transfer_slots: 256 is out of range 1..255" },
		{ "\"max_transfers_per_client\": 3",
		  "mailbox.max_transfers_per_client: 3 is more than transfer_slots (2)" },
		{ "\"transfer_stall_ms\": 5",
		  "mailbox.transfer_stall_ms: 5 is out of range 10..600000" },
		{ "\"transfer_lifetime_ms\": 0",
		  "mailbox.transfer_lifetime_ms: 0 is out of range 100..86400000" },
		{ "\"transfer_lifetime_ms\": 86400001",
		  "mailbox.transfer_lifetime_ms: 86400001 is out of range 100..86400000" },
		{ "\"transfer_memory\": 100",
		  "mailbox.transfer_memory: 100 is out of range 4096..4294967295" },
		{ "\"max_transfer\": 33554432",
		  "mailbox.transfer_memory: 16777216 is less than max_transfer (33554432): no "
		  "transfer that large could run" },
	};
	for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
		char json[512], want[256];

		snprintf(json, sizeof json, "{\"mailbox\": {%s}, \"lines\": [" LINE("") "]}",
			 bad[i].mailbox);
		snprintf(want, sizeof want, "t.json: %s", bad[i].error);
		expect_error(json, want);
	}
	/* and the good ones reach the configuration */
	load_ok("{\"mailbox\": {\"max_clients\": 8, \"write_reserve\": 3, "
		"\"max_read_outstanding\": 5, \"transfer_slots\": 4, "
		"\"max_transfers_per_client\": 3, \"transfer_stall_ms\": 700, "
		"\"transfer_lifetime_ms\": 2500, \"max_transfer\": 33554432, "
		"\"transfer_memory\": 67108864}, \"lines\": [" LINE("") "]}");
	TEST_ASSERT_EQUAL_UINT(3, cfg.mailbox.write_reserve);
	TEST_ASSERT_EQUAL_UINT(5, cfg.mailbox.max_read_outstanding);
	TEST_ASSERT_EQUAL_UINT(4, cfg.mailbox.transfer_slots);
	TEST_ASSERT_EQUAL_UINT(3, cfg.mailbox.max_transfers_per_client);
	TEST_ASSERT_EQUAL_UINT(700, cfg.mailbox.transfer_stall_ms);
	TEST_ASSERT_EQUAL_UINT(2500, cfg.mailbox.transfer_lifetime_ms);
	TEST_ASSERT_EQUAL_UINT(64u << 20, cfg.mailbox.transfer_memory);
}

static void test_missing_required_keys(void)
{
	expect_error("{}", "t.json: lines: required key is missing");
	expect_error("{\"lines\": [{\"bitrate\": 500000, \"node_id\": 5}]}",
		     "t.json: lines[0].interface: required key is missing");
	expect_error("{\"lines\": [{\"interface\": \"can0\", \"node_id\": 5}]}",
		     "t.json: lines[0].bitrate: required key is missing");
	expect_error(CFG1(", \"heartbeat_consumers\": [{\"node_id\": 3}]"),
		     "t.json: lines[0].heartbeat_consumers[0].time_ms: required key is missing");
}

static void test_out_of_range(void)
{
	expect_error("{\"lines\": [" LINE("") ", {\"interface\": \"vcan1\", "
					      "\"bitrate\": 500000, \"node_id\": 200}]}",
		     "t.json: lines[1].node_id: 200 is out of range 1..127");
	expect_error(CFG1(", \"heartbeat_ms\": 70000"),
		     "t.json: lines[0].heartbeat_ms: 70000 is out of range 0..65535");
	expect_error(CFG1(", \"rt\": {\"priority\": 100}"),
		     "t.json: lines[0].rt.priority: 100 is out of range 0..99");
	expect_error(CFG1(", \"network_id\": 0"),
		     "t.json: lines[0].network_id: 0 is out of range 1..127");
	expect_error("{\"mailbox\": {\"msg_size\": 100}, \"lines\": [" LINE("") "]}",
		     "t.json: mailbox.msg_size: 100 is out of range 256..65535");
	expect_error(
		CFG1(", \"heartbeat_consumers\": [{\"node_id\": 5, \"time_ms\": 100}]"),
		"t.json: lines[0].heartbeat_consumers[0].node_id: 5 is this line's own node id");
	expect_error(CFG1(", \"heartbeat_consumers\": [{\"node_id\": 3, \"time_ms\": 100},"
			  " {\"node_id\": 3, \"time_ms\": 200}]"),
		     "t.json: lines[0].heartbeat_consumers[1].node_id: node 3 is already monitored "
		     "(lines[0].heartbeat_consumers[0])");
}

static void test_unknown_keys(void)
{
	expect_error(CFG1(", \"bitrat\": 500000"),
		     "t.json: lines[0].bitrat: unknown key (did you mean \"bitrate\"?)");
	expect_error("{\"lines\": [" LINE("") "], \"frobnicate\": 1}",
		     "t.json: frobnicate: unknown key");
	expect_error(CFG1(", \"rt\": {\"prio\": 10}"), "t.json: lines[0].rt.prio: unknown key");
	expect_error("{\"mailbox\": {\"instanse\": \"x\"}, \"lines\": [" LINE("") "]}",
		     "t.json: mailbox.instanse: unknown key (did you mean \"instance\"?)");
	/* cJSON keeps duplicate keys; we do not. */
	expect_error(CFG1(", \"node_id\": 6"), "t.json: lines[0].node_id: duplicate key");
}

static void test_duplicate_lines(void)
{
	expect_error("{\"lines\": [" LINE(
			     ", \"name\": \"a\"") ", "
						  "{\"name\": \"a\", \"interface\": \"vcan1\", "
						  "\"bitrate\": 500000, \"node_id\": 5}]}",
		     "t.json: lines[1].name: \"a\" is already used by lines[0]");
	expect_error("{\"lines\": [" LINE("") ", " LINE("") "]}",
		     "t.json: lines[1].interface: \"vcan0\" is already used by lines[0]");
	expect_error("{\"lines\": [" LINE(
			     ", \"network_id\": 7") ", "
						    "{\"interface\": \"vcan1\", \"bitrate\": "
						    "500000, \"node_id\": 5, \"network_id\": 7}]}",
		     "t.json: lines[1].network_id: 7 is already used by lines[0]");
}

static void test_interface_and_names(void)
{
	expect_error("{\"lines\": [{\"interface\": \"averyveryverylongcan0\", \"bitrate\": 500000, "
		     "\"node_id\": 5}]}",
		     "t.json: lines[0].interface: \"averyveryverylongcan0\" is too long (21 bytes, "
		     "at most 15)");
	expect_error(
		"{\"lines\": [{\"interface\": \"can/0\", \"bitrate\": 500000, \"node_id\": 5}]}",
		"t.json: lines[0].interface: \"can/0\" is not a valid interface name");
	expect_error(
		CFG1(", \"name\": \"line 0\""),
		"t.json: lines[0].name: \"line 0\" may contain only letters, digits, '_' and '-'");
	expect_error("{\"mailbox\": {\"instance\": \"\"}, \"lines\": [" LINE("") "]}",
		     "t.json: mailbox.instance: must not be empty");
}

static void test_bitrate_not_cia(void)
{
	expect_error(
		"{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 100000, \"node_id\": 5}]}",
		"t.json: lines[0].bitrate: 100000 is not a CiA 301 bit rate (10000, 20000, 50000, "
		"125000, 250000, 500000, 800000, 1000000)");
	/* Every CiA 301 rate is accepted. */
	static const char *const ok[] = { "10000",  "20000",  "50000",  "125000",
					  "250000", "500000", "800000", "1000000" };
	for (size_t i = 0; i < 8; i++) {
		char json[160];

		snprintf(json, sizeof(json),
			 "{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": %s, \"node_id\": "
			 "5}]}",
			 ok[i]);
		load_ok(json);
		TEST_ASSERT_EQUAL_UINT32(strtoul(ok[i], NULL, 10), cfg.lines[0].bitrate);
		cogw_config_free(&cfg);
	}
}

static void test_too_many_lines_and_rules(void)
{
	char json[8192];
	size_t n = 0;

	n += (size_t)snprintf(json + n, sizeof(json) - n, "{\"lines\": [");
	for (int i = 0; i <= COGW_LINES_MAX; i++)
		n += (size_t)snprintf(
			json + n, sizeof(json) - n,
			"%s{\"interface\": \"vcan%d\", \"bitrate\": 500000, \"node_id\": 5}",
			i ? ", " : "", i);
	snprintf(json + n, sizeof(json) - n, "]}");
	expect_error(json, "t.json: lines: 17 lines, at most 16");

	n = 0;
	n += (size_t)snprintf(json + n, sizeof(json) - n, "{\"mailbox\": {\"rules\": [");
	for (int i = 0; i <= COGW_ACCESS_RULES_MAX; i++)
		n += (size_t)snprintf(json + n, sizeof(json) - n,
				      "%s{\"uid\": %d, \"access\": \"read\"}", i ? ", " : "",
				      1000 + i);
	snprintf(json + n, sizeof(json) - n, "]}, \"lines\": [" LINE("") "]}");
	expect_error(json, "t.json: mailbox.rules: 65 rules, at most 64");
}

static void test_access_rules(void)
{
	expect_error("{\"mailbox\": {\"rules\": [{\"user\": \"no-such-user-cogw\", \"access\": "
		     "\"read\"}]}, \"lines\": [" LINE("") "]}",
		     "t.json: mailbox.rules[0].user: unknown user \"no-such-user-cogw\"");
	expect_error("{\"mailbox\": {\"rules\": [{\"uid\": 0, \"access\": \"admin\"}]}, \"lines\": "
		     "[" LINE("") "]}",
		     "t.json: mailbox.rules[0].access: unknown access \"admin\" (one of none, "
		     "read, write)");
	expect_error("{\"mailbox\": {\"rules\": [{\"uid\": 0, \"user\": \"root\", \"access\": "
		     "\"read\"}]}, \"lines\": [" LINE("") "]}",
		     "t.json: mailbox.rules[0]: give either \"user\" or \"uid\"");
	expect_error("{\"mailbox\": {\"rules\": [{\"uid\": 0, \"access\": \"read\"}, {\"user\": "
		     "\"root\", \"access\": \"write\"}]}, \"lines\": [" LINE("") "]}",
		     "t.json: mailbox.rules[1]: uid 0 already has a rule (mailbox.rules[0])");
	expect_error("{\"mailbox\": {\"default_access\": \"all\"}, \"lines\": [" LINE("") "]}",
		     "t.json: mailbox.default_access: unknown access \"all\" (one of none, read, "
		     "write)");

	load_ok("{\"mailbox\": {\"default_access\": \"none\", \"lease_ms\": 5000, \"rules\": ["
		"{\"user\": \"root\", \"access\": \"write\"}, {\"uid\": 1000, \"access\": "
		"\"read\"}]}, "
		"\"lines\": [" LINE("") "]}");
	TEST_ASSERT_EQUAL_UINT8(COGW_ACCESS_NONE, cfg.mailbox.default_access);
	TEST_ASSERT_EQUAL_size_t(2, cfg.mailbox.n_rules);
	TEST_ASSERT_EQUAL_UINT32(0, cfg.mailbox.rules[0].uid);
	TEST_ASSERT_EQUAL_UINT8(COGW_ACCESS_WRITE, cfg.mailbox.rules[0].access);
	TEST_ASSERT_EQUAL_UINT32(1000, cfg.mailbox.rules[1].uid);
	TEST_ASSERT_EQUAL_UINT8(COGW_ACCESS_READ, cfg.mailbox.rules[1].access);
	TEST_ASSERT_EQUAL_UINT(5000, cfg.mailbox.lease_ms);
}

static void test_bad_object_definitions(void)
{
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2000\", \"type\": \"UNSIGNED33\"}]"),
		     "t.json: lines[0].objects[0].type: unknown type \"UNSIGNED33\"");
	expect_error(
		CFG1(", \"objects\": [{\"index\": \"0x0FFF\", \"type\": \"UNSIGNED8\"}]"),
		"t.json: lines[0].objects[0].index: \"0x0FFF\" is out of range 0x1000..0xFFFF");
	expect_error(CFG1(", \"objects\": [{\"index\": 70000, \"type\": \"UNSIGNED8\"}]"),
		     "t.json: lines[0].objects[0].index: 70000 is out of range 0x1000..0xFFFF");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x1017\", \"type\": \"UNSIGNED16\"}]"),
		     "t.json: lines[0].objects[0].index: object 0x1017 already exists (a standard "
		     "object or defined twice; set values in \"values\")");
	expect_error(CFG1(", \"objects\": [{\"index\": 8192, \"type\": \"UNSIGNED8\"},"
			  " {\"index\": \"0x2000\", \"type\": \"UNSIGNED8\"}]"),
		     "t.json: lines[0].objects[1].index: object 0x2000 already exists (a standard "
		     "object or defined twice; set values in \"values\")");
	expect_error(
		CFG1(", \"objects\": [{\"index\": \"0x2001\", \"object\": \"RECORD\", \"subs\": ["
		     "{\"sub\": 1, \"type\": \"UNSIGNED8\"}, {\"sub\": 1, \"type\": "
		     "\"UNSIGNED16\"}]}]"),
		"t.json: lines[0].objects[0].subs[1].sub: sub-index 1 is defined twice");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2002\", \"type\": \"INTEGER16\", "
			  "\"min\": -100, \"max\": 100, \"default\": 2000}]"),
		     "t.json: lines[0].objects[0].default: default 2000 is above max 100");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2002\", \"type\": \"INTEGER16\", "
			  "\"min\": 10, \"max\": 100}]"),
		     "t.json: lines[0].objects[0]: default 0 (implicit) is below min 10");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2002\", \"type\": \"REAL32\", "
			  "\"min\": 5.5, \"max\": 1.25}]"),
		     "t.json: lines[0].objects[0].min: min 5.5 is greater than max 1.25");
	expect_error(
		CFG1(", \"objects\": [{\"index\": \"0x2003\", \"type\": \"VISIBLE_STRING\", "
		     "\"max_size\": 4, \"default\": \"hello\"}]"),
		"t.json: lines[0].objects[0].default: string of 5 bytes is longer than max_size 4");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2003\", \"type\": \"VISIBLE_STRING\"}]"),
		     "t.json: lines[0].objects[0].max_size: required for VISIBLE_STRING without a "
		     "non-empty default");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2004\", \"type\": \"UNSIGNED8\", "
			  "\"access\": \"rx\"}]"),
		     "t.json: lines[0].objects[0].access: unknown access \"rx\" (one of ro, wo, "
		     "rw, rwr, rww, const)");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2004\", \"type\": \"UNSIGNED8\", "
			  "\"default\": 256}]"),
		     "t.json: lines[0].objects[0].default: 256 is out of range 0..255");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2004\", \"type\": \"UNSIGNED8\", "
			  "\"lenght\": 2}]"),
		     "t.json: lines[0].objects[0].lenght: unknown key");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2005\", \"object\": \"ARRAY\", "
			  "\"type\": \"UNSIGNED8\","
			  " \"length\": 2, \"defaults\": [1, 2, 3]}]"),
		     "t.json: lines[0].objects[0].defaults: has 3 values, length is 2");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2006\", \"type\": \"OCTET_STRING\", "
			  "\"default\": \"0g\"}]"),
		     "t.json: lines[0].objects[0].default: not a hex string (pairs of hex digits, "
		     "optionally separated by spaces)");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2007\", \"type\": \"VISIBLE_STRING\", "
			  "\"max_size\": 8, \"min\": 1}]"),
		     "t.json: lines[0].objects[0].min: limits apply to numeric types only, not "
		     "VISIBLE_STRING");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2008\", \"object\": \"STRUCT\"}]"),
		     "t.json: lines[0].objects[0].object: unknown object code \"STRUCT\" (VAR, "
		     "ARRAY or RECORD)");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2009\", \"type\": \"UNSIGNED64\", "
			  "\"default\": 18446744073709551615}]"),
		     "t.json: lines[0].objects[0].default: 1.8446744073709552e+19 is beyond the "
		     "exact range of JSON numbers; write it as a string (\"0x...\")");
}

/* "app": objects clients own (docs/application.md), checked against the
 * line's objects. */
#define APP_OBJS                                                                                  \
	", \"objects\": [{\"index\": \"0x2100\", \"type\": \"UNSIGNED32\"},"                      \
	" {\"index\": \"0x2101\", \"type\": \"UNSIGNED16\", \"access\": \"rwr\", \"pdo\": true}," \
	" {\"index\": \"0xA000\", \"type\": \"UNSIGNED8\"}]"

static void test_app_objects(void)
{
	load_ok(CFG1(APP_OBJS ", \"app\": {\"indications\": 4, \"objects\": ["
			      "{\"index\": \"0x2100\", \"kind\": \"served\", \"uid\": 1001},"
			      "{\"index\": \"0x2101\", \"kind\": \"held\", \"user\": \"root\"}]}"));
	const cogw_app_config *a = &cfg.lines[0].app;
	TEST_ASSERT_EQUAL(2, a->n_decl);
	TEST_ASSERT_EQUAL_HEX16(0x2100, a->decl[0].index);
	TEST_ASSERT_EQUAL(MBX_APP_SERVED, a->decl[0].kind);
	TEST_ASSERT_EQUAL(1001, a->decl[0].uid);
	TEST_ASSERT_EQUAL(MBX_APP_HELD, a->decl[1].kind);
	TEST_ASSERT_EQUAL(0, a->decl[1].uid);
	TEST_ASSERT_EQUAL(100, a->max_created);
	TEST_ASSERT_EQUAL(64, a->max_per_client);
	TEST_ASSERT_EQUAL(4, a->indications);
	cogw_config_free(&cfg);
	memset(&cfg, 0, sizeof cfg);
	expect_error(CFG1(APP_OBJS ", \"app\": {\"objects\": [{\"index\": \"0x2102\", "
				   "\"kind\": \"held\", \"uid\": 1}]}"),
		     "t.json: lines[0].app.objects[0]: 2102h:0 is not in the line's \"objects\"");
	expect_error(CFG1(APP_OBJS ", \"app\": {\"objects\": [{\"index\": \"0xA000\", "
				   "\"kind\": \"held\", \"uid\": 1}]}"),
		     "t.json: lines[0].app.objects[0].index: A000h: objects clients own are in "
		     "2000h..9FFFh");
	expect_error(CFG1(APP_OBJS ", \"app\": {\"objects\": [{\"index\": \"0x1017\", "
				   "\"kind\": \"held\", \"uid\": 1}]}"),
		     "t.json: lines[0].app.objects[0].index: 1017h: objects clients own are in "
		     "2000h..9FFFh");
	expect_error(CFG1(APP_OBJS ", \"app\": {\"objects\": [{\"index\": \"0x2101\", "
				   "\"kind\": \"served\", \"uid\": 1}]}"),
		     "t.json: lines[0].app.objects[0]: 2101h:0: a served object cannot be "
		     "PDO-mappable");
	expect_error(
		CFG1(APP_OBJS ", \"app\": {\"objects\": [{\"index\": \"0x2100\", "
			      "\"kind\": \"mine\", \"uid\": 1}]}"),
		"t.json: lines[0].app.objects[0].kind: unknown kind \"mine\" (held or served)");
	expect_error(CFG1(APP_OBJS ", \"app\": {\"objects\": [{\"index\": \"0x2100\", "
				   "\"kind\": \"held\"}]}"),
		     "t.json: lines[0].app.objects[0]: give either \"user\" or \"uid\"");
	expect_error(CFG1(APP_OBJS ", \"app\": {\"objects\": ["
				   "{\"index\": \"0x2100\", \"kind\": \"held\", \"uid\": 1},"
				   "{\"index\": \"0x2100\", \"kind\": \"held\", \"uid\": 2}]}"),
		     "t.json: lines[0].app.objects[1]: 2100h:0 declared twice");
	expect_error(CFG1(APP_OBJS ", \"app\": {\"indications\": 33}"),
		     "t.json: lines[0].app.indications: 33 is out of range 1..32");
}

static void test_bad_values(void)
{
	expect_error(CFG1(", \"values\": [{\"index\": \"0x2FFF\", \"value\": 1}]"),
		     "t.json: lines[0].values[0].index: object 0x2FFF does not exist");
	expect_error(CFG1(", \"values\": [{\"index\": \"0x1018\", \"sub\": 9, \"value\": 1}]"),
		     "t.json: lines[0].values[0].sub: object 0x1018 has no sub-index 9");
	expect_error(CFG1(", \"values\": [{\"index\": \"0x1017\", \"value\": \"fast\"}]"),
		     "t.json: lines[0].values[0].value: \"fast\" is not an integer");
	expect_error(CFG1(", \"values\": [{\"index\": \"0x1008\", \"value\": 5}]"),
		     "t.json: lines[0].values[0].value: expected a string for VISIBLE_STRING, got "
		     "a number");
	expect_error(CFG1(", \"values\": [{\"index\": \"0x1017\", \"value\": 65536}]"),
		     "t.json: lines[0].values[0].value: 65536 is out of range 0..65535");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0x2000\", \"type\": \"UNSIGNED16\", "
			  "\"min\": 10, \"max\": 1000, \"default\": 10}],"
			  " \"values\": [{\"index\": \"0x2000\", \"value\": 1001}]"),
		     "t.json: lines[0].values[0].value: 1001 refused for 0x2000:00 (value of "
		     "parameter too high)");
	expect_error(CFG1(", \"values\": [{\"index\": \"0x1017\", \"value\": 10},"
			  " {\"index\": 4119, \"sub\": 0, \"value\": 20}]"),
		     "t.json: lines[0].values[1]: 0x1017:00 is already set by lines[0].values[0]");
	expect_error(CFG1(", \"values\": [{\"index\": \"0x1017\"}]"),
		     "t.json: lines[0].values[0].value: required key is missing");
	expect_error(CFG1(", \"values\": {\"0x1017\": 5}"),
		     "t.json: lines[0].values: expected an array of {\"index\", \"sub\", "
		     "\"value\"}, got an object");
}

/* ---- what the ODs contain ----------------------------------------------------------- */

static const char *typed_json = CFG1(
	", \"objects\": ["
	"{\"index\": \"0x2000\", \"name\": \"Pressure\", \"type\": \"INTEGER16\", \"access\": "
	"\"rwr\","
	" \"min\": -1000, \"max\": 1000, \"default\": -5},"
	"{\"index\": \"0x2001\", \"type\": \"REAL32\", \"default\": 1.5},"
	"{\"index\": \"0x2002\", \"type\": \"REAL64\", \"default\": -0.25, \"access\": \"ro\"},"
	"{\"index\": \"0x2003\", \"type\": \"INTEGER64\", \"default\": \"-9223372036854775808\"},"
	"{\"index\": \"0x2004\", \"type\": \"UNSIGNED64\", \"default\": \"0xFFFFFFFFFFFFFFFF\"},"
	"{\"index\": \"0x2005\", \"type\": \"INTEGER24\", \"default\": -2},"
	"{\"index\": \"0x2006\", \"type\": \"BOOLEAN\", \"default\": true, \"pdo\": true},"
	"{\"index\": \"0x2007\", \"type\": \"VISIBLE_STRING\", \"max_size\": 16, \"default\": "
	"\"abc\"},"
	"{\"index\": \"0x2008\", \"type\": \"OCTET_STRING\", \"default\": \"01 02 ff\"},"
	"{\"index\": \"0x2009\", \"type\": \"DOMAIN\", \"max_size\": 4096},"
	"{\"index\": \"0x200A\", \"type\": \"UNICODE_STRING\", \"default\": \"A\\u00e9\"},"
	"{\"index\": \"0x200B\", \"type\": \"TIME_OF_DAY\", \"default\": {\"ms\": 1000, \"days\": "
	"2}},"
	"{\"index\": \"0x200C\", \"type\": \"UNSIGNED48\", \"default\": \"0x123456789ABC\", "
	"\"persist\": true},"
	"{\"index\": \"0x2100\", \"object\": \"ARRAY\", \"type\": \"UNSIGNED16\", \"length\": 3,"
	" \"defaults\": [1, 2, \"0x10\"], \"access\": \"rww\"},"
	"{\"index\": \"0x2200\", \"object\": \"RECORD\", \"name\": \"rec\", \"subs\": ["
	" {\"sub\": 1, \"type\": \"UNSIGNED8\", \"default\": 7},"
	" {\"sub\": 3, \"type\": \"INTEGER32\", \"access\": \"const\", \"default\": -7}]}"
	"], \"values\": ["
	"{\"index\": \"0x2000\", \"value\": 999},"
	"{\"index\": \"0x2007\", \"value\": \"changed\"},"
	"{\"index\": \"0x1008\", \"value\": \"my gateway\"},"
	"{\"index\": \"0x1018\", \"sub\": 1, \"value\": \"0x0000ABCD\"},"
	"{\"index\": \"0x2001\", \"value\": -3.25}"
	"]");

static void test_od_typed_values(void)
{
	co_od *od;
	co_od_entry *e;
	uint8_t buf[32];
	uint32_t len;
	float f;
	double d;
	int64_t i64;
	uint64_t u64;

	load_ok(typed_json);
	od = cfg.lines[0].od;

	e = co_od_find(od, 0x2000, 0);
	TEST_ASSERT_NOT_NULL(e);
	TEST_ASSERT_EQUAL_UINT8(CO_T_INTEGER16, e->type);
	TEST_ASSERT_EQUAL_HEX16(CO_ACC_RWR, e->access);
	TEST_ASSERT_EQUAL_STRING("Pressure", e->name);
	TEST_ASSERT_EQUAL_HEX64(999, co_od_entry_raw(e)); /* value applied */
	TEST_ASSERT_EQUAL_HEX8(0xE7, e->def[0]);          /* and it is the default */
	TEST_ASSERT_EQUAL_HEX8(0x03, e->def[1]);

	TEST_ASSERT_EQUAL_INT(0, co_od_get_r32(od, 0x2001, 0, &f));
	TEST_ASSERT_EQUAL_FLOAT(-3.25f, f);
	TEST_ASSERT_EQUAL_INT(0, co_od_get_r64(od, 0x2002, 0, &d));
	TEST_ASSERT_EQUAL_DOUBLE(-0.25, d);
	TEST_ASSERT_EQUAL_HEX16(CO_ACC_RO, co_od_find(od, 0x2002, 0)->access);
	TEST_ASSERT_EQUAL_INT(0, co_od_get_i64(od, 0x2003, 0, &i64));
	TEST_ASSERT_TRUE(i64 == INT64_MIN);
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u64(od, 0x2004, 0, &u64));
	TEST_ASSERT_TRUE(u64 == UINT64_MAX);
	e = co_od_find(od, 0x2005, 0);
	TEST_ASSERT_EQUAL_UINT32(3, e->size);
	TEST_ASSERT_EQUAL_HEX64(0xFFFFFE, co_od_entry_raw(e));
	e = co_od_find(od, 0x2006, 0);
	TEST_ASSERT_EQUAL_HEX64(1, co_od_entry_raw(e));
	TEST_ASSERT_EQUAL_HEX16(CO_ACC_RW | CO_ACC_RPDO | CO_ACC_TPDO, e->access);

	e = co_od_find(od, 0x2007, 0);
	TEST_ASSERT_EQUAL_UINT32(16, e->max_size);
	TEST_ASSERT_EQUAL_UINT32(7, e->size);
	TEST_ASSERT_EQUAL_MEMORY("changed", e->data, 7);

	TEST_ASSERT_EQUAL_INT(0, co_od_get_bytes(od, 0x2008, 0, buf, sizeof(buf), &len));
	TEST_ASSERT_EQUAL_UINT32(3, len);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(((uint8_t[]){ 0x01, 0x02, 0xFF }), buf, 3);
	TEST_ASSERT_EQUAL_UINT32(3, co_od_find(od, 0x2008, 0)->max_size);

	e = co_od_find(od, 0x2009, 0);
	TEST_ASSERT_EQUAL_UINT8(CO_T_DOMAIN, e->type);
	TEST_ASSERT_EQUAL_UINT32(4096, e->max_size);
	TEST_ASSERT_EQUAL_UINT32(0, e->size);

	/* "Aé" in UTF-16LE. */
	TEST_ASSERT_EQUAL_INT(0, co_od_get_bytes(od, 0x200A, 0, buf, sizeof(buf), &len));
	TEST_ASSERT_EQUAL_UINT32(4, len);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(((uint8_t[]){ 0x41, 0x00, 0xE9, 0x00 }), buf, 4);

	TEST_ASSERT_EQUAL_INT(0, co_od_get_bytes(od, 0x200B, 0, buf, sizeof(buf), &len));
	TEST_ASSERT_EQUAL_UINT32(6, len);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(((uint8_t[]){ 0xE8, 0x03, 0x00, 0x00, 0x02, 0x00 }), buf, 6);

	e = co_od_find(od, 0x200C, 0);
	TEST_ASSERT_EQUAL_HEX64(0x123456789ABCull, co_od_entry_raw(e));
	TEST_ASSERT_TRUE(e->access & CO_ACC_PERSIST);

	/* ARRAY: sub 0 = length, per-sub defaults. */
	e = co_od_find(od, 0x2100, 0);
	TEST_ASSERT_EQUAL_UINT8(CO_OBJ_ARRAY, e->obj_code);
	TEST_ASSERT_EQUAL_HEX64(3, co_od_entry_raw(e));
	TEST_ASSERT_EQUAL_HEX64(1, raw(od, 0x2100, 1));
	TEST_ASSERT_EQUAL_HEX64(2, raw(od, 0x2100, 2));
	TEST_ASSERT_EQUAL_HEX64(0x10, raw(od, 0x2100, 3));
	TEST_ASSERT_EQUAL_HEX16(CO_ACC_RWW, co_od_find(od, 0x2100, 3)->access);

	/* RECORD: sub 0 = highest sub, gaps stay gaps. */
	TEST_ASSERT_EQUAL_HEX64(3, raw(od, 0x2200, 0));
	TEST_ASSERT_EQUAL_UINT8(CO_OBJ_RECORD, co_od_find(od, 0x2200, 3)->obj_code);
	TEST_ASSERT_NULL(co_od_find(od, 0x2200, 2));
	TEST_ASSERT_EQUAL_HEX64(0xFFFFFFF9, raw(od, 0x2200, 3));
	TEST_ASSERT_EQUAL_HEX16(CO_ACC_CO, co_od_find(od, 0x2200, 3)->access);

	/* Values on standard objects, including const/ro ones. */
	TEST_ASSERT_EQUAL_INT(0, co_od_get_bytes(od, 0x1008, 0, buf, sizeof(buf), &len));
	TEST_ASSERT_EQUAL_UINT32(10, len);
	TEST_ASSERT_EQUAL_MEMORY("my gateway", buf, 10);
	TEST_ASSERT_EQUAL_HEX64(0xABCD, raw(od, 0x1018, 1));
}

static void test_limits_enforced_after_load(void)
{
	co_od_entry *e;
	co_od_access a = { .origin = CO_OD_ORIGIN_SDO };
	uint8_t v[2];

	load_ok(typed_json);
	e = co_od_find(cfg.lines[0].od, 0x2000, 0);
	v[0] = 0xE9; /* 1001 */
	v[1] = 0x03;
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_HIGH, co_od_write(e, v, 2, &a));
	TEST_ASSERT_EQUAL_HEX64(999, co_od_entry_raw(e));
	v[0] = 0x17; /* -1001 = 0xFC17 */
	v[1] = 0xFC;
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_LOW, co_od_write(e, v, 2, &a));
	v[0] = 0x18; /* -1000 */
	v[1] = 0xFC;
	TEST_ASSERT_EQUAL_HEX32(0, co_od_write(e, v, 2, &a));
	TEST_ASSERT_EQUAL_HEX64(0xFC18, co_od_entry_raw(e));
	/* A string beyond its max_size is refused like over SDO. */
	e = co_od_find(cfg.lines[0].od, 0x2007, 0);
	TEST_ASSERT_NOT_EQUAL(0, co_od_write(e, (const uint8_t *)"0123456789abcdefg", 17, &a));
	/* Configured values are defaults: a reset returns to them. */
	co_od_reset_range(cfg.lines[0].od, 0x0000, 0xFFFF);
	TEST_ASSERT_EQUAL_HEX64(999, raw(cfg.lines[0].od, 0x2000, 0));
	TEST_ASSERT_EQUAL_MEMORY("changed", co_od_find(cfg.lines[0].od, 0x2007, 0)->data, 7);
}

static void test_values_update_structured_keys(void)
{
	load_ok(CFG1(", \"heartbeat_ms\": 200, \"values\": ["
		     "{\"index\": \"0x1017\", \"value\": 250},"
		     "{\"index\": \"0x1016\", \"sub\": 2, \"value\": \"0x000703E8\"}]"));
	TEST_ASSERT_EQUAL_UINT16(250, cfg.lines[0].heartbeat_ms);
	TEST_ASSERT_EQUAL_size_t(1, cfg.lines[0].n_hb_consumers);
	TEST_ASSERT_EQUAL_UINT8(7, cfg.lines[0].hb_consumers[0].node_id);
	TEST_ASSERT_EQUAL_UINT16(1000, cfg.lines[0].hb_consumers[0].time_ms);
}

static void test_sync_producer_and_pdos(void)
{
	co_od *od;

	load_ok(CFG1(
		", \"sync_period_us\": 10000, \"rpdos\": 5, \"tpdos\": 2, \"sdo_servers\": 2"));
	od = cfg.lines[0].od;
	TEST_ASSERT_EQUAL_HEX64(0x40000080u, raw(od, 0x1005, 0));
	TEST_ASSERT_EQUAL_HEX64(10000, raw(od, 0x1006, 0));
	/* Predefined connection set, not valid until mapped. */
	TEST_ASSERT_EQUAL_HEX64(0x80000205u, raw(od, 0x1400, 1));
	TEST_ASSERT_EQUAL_HEX64(0x80000505u, raw(od, 0x1403, 1));
	TEST_ASSERT_EQUAL_HEX64(0x80000000u, raw(od, 0x1404, 1));
	TEST_ASSERT_EQUAL_HEX64(0x80000185u, raw(od, 0x1800, 1));
	TEST_ASSERT_EQUAL_HEX64(0x80000285u, raw(od, 0x1801, 1));
	TEST_ASSERT_NULL(co_od_find(od, 0x1802, 1));
	TEST_ASSERT_EQUAL_HEX64(3, raw(od, 0x1201, 0));
	TEST_ASSERT_EQUAL_HEX64(0x80000000u, raw(od, 0x1201, 1));
	/* Our own EMCY is not consumed; others are. */
	TEST_ASSERT_EQUAL_HEX64(0x80000085u, raw(od, 0x1028, 5));
	TEST_ASSERT_EQUAL_HEX64(0x84, raw(od, 0x1028, 4));
}

/* ---- reload --------------------------------------------------------------------------- */

static void test_reload_check(void)
{
	cogw_config next;
	char what[256];

	load_default();
	memset(&next, 0, sizeof(next));
	TEST_ASSERT_EQUAL_INT(0, cogw_config_load_string(&next, cogw_default_config_json,
							 COGW_DEFAULT_CONFIG_SOURCE, err,
							 sizeof(err)));
	TEST_ASSERT_TRUE(cogw_config_reload_check(&cfg, &next, what, sizeof(what)));
	TEST_ASSERT_EQUAL_STRING("", what);
	cogw_config_free(&next);

	/* What may change: rules, lease, heartbeat, RT; against the default's
	 * lines without their managers (the configuration of the tests that
	 * start nodes by hand), which the texts below spell out. */
	cogw_config_free(&cfg);
	memset(&cfg, 0, sizeof(cfg));
	TEST_ASSERT_EQUAL_INT(0, cogw_config_load_file(&cfg,
						       "tests/integration/config/hand-started.json",
						       err, sizeof(err)));
	TEST_ASSERT_EQUAL_INT(
		0, cogw_config_load_string(
			   &next,
			   "{\"mailbox\": {\"lease_ms\": 3000, \"default_access\": \"read\","
			   " \"rules\": [{\"uid\": 0, \"access\": \"write\"}]},"
			   /* the default's shared process image B000h, unchanged */
			   " \"gateway\": {\"process_image\": [{\"index\": \"0xB000\", \"type\": "
			   "\"REAL32\","
			   " \"access\": \"rw\", \"pdo\": true, \"name\": \"pressure of node 1 "
			   "(PSI, shared process image)\"}]},"
			   " \"lines\": ["
			   "{\"name\": \"line0\", \"interface\": \"vcan0\", \"bitrate\": 1000000, "
			   "\"node_id\": 127,"
			   " \"network_id\": 1, \"heartbeat_ms\": 500, \"rt\": {\"priority\": 50, "
			   "\"cpu\": 1},"
			   " \"heartbeat_consumers\": [{\"node_id\": 1, \"time_ms\": 3000}, "
			   "{\"node_id\": 9, \"time_ms\": 3000}],"
			   " \"device\": {\"name\": \"cogw gateway\"},"
			   /* the default's demo RPDO into B000h, unchanged */
			   " \"rpdos\": 1,"
			   " \"values\": [{\"index\": \"0x1400\", \"sub\": 1, \"value\": "
			   "\"0x00000181\"},"
			   " {\"index\": \"0x1600\", \"sub\": 1, \"value\": \"0xB0000020\"}, "
			   "{\"index\": \"0x1600\", \"sub\": 0, \"value\": 1}]},"
			   "{\"name\": \"line1\", \"interface\": \"vcan1\", \"bitrate\": 1000000, "
			   "\"node_id\": 127,"
			   " \"network_id\": 2, \"device\": {\"name\": \"cogw gateway\"}},"
			   "{\"name\": \"line2\", \"interface\": \"vcan2\", \"bitrate\": 1000000, "
			   "\"node_id\": 127,"
			   " \"network_id\": 3, \"device\": {\"name\": \"cogw gateway\"}}]}",
			   "next", err, sizeof(err)));
	TEST_ASSERT_TRUE_MESSAGE(cogw_config_reload_check(&cfg, &next, what, sizeof(what)), what);
	TEST_ASSERT_EQUAL_STRING("", what);
	cogw_config_free(&next);

	/* What may not. */
	TEST_ASSERT_EQUAL_INT(
		0, cogw_config_load_string(
			   &next,
			   "{\"mailbox\": {\"depth\": 32},"
			   " \"gateway\": {\"process_image\": [{\"index\": \"0xB000\", \"type\": "
			   "\"REAL32\","
			   " \"access\": \"rw\", \"pdo\": true, \"name\": \"pressure of node 1 "
			   "(PSI, shared process image)\"}]},"
			   " \"lines\": ["
			   "{\"name\": \"line0\", \"interface\": \"vcan0\", \"bitrate\": 500000, "
			   "\"node_id\": 127,"
			   " \"network_id\": 1, \"device\": {\"name\": \"cogw gateway\"}},"
			   "{\"name\": \"line1\", \"interface\": \"vcan1\", \"bitrate\": 1000000, "
			   "\"node_id\": 127,"
			   " \"network_id\": 2, \"device\": {\"name\": \"cogw gateway\"},"
			   " \"objects\": [{\"index\": \"0x2000\", \"type\": \"UNSIGNED8\"}]},"
			   "{\"name\": \"line2\", \"interface\": \"vcan2\", \"bitrate\": 1000000, "
			   "\"node_id\": 127,"
			   " \"network_id\": 3}]}",
			   "next", err, sizeof(err)));
	TEST_ASSERT_FALSE(cogw_config_reload_check(&cfg, &next, what, sizeof(what)));
	TEST_ASSERT_EQUAL_STRING("mailbox.depth: needs a restart; lines[0].bitrate: needs a "
				 "restart; lines[1].objects/values: needs a restart; "
				 "lines[2].objects/values: needs a restart",
				 what);
	cogw_config_free(&next);

	TEST_ASSERT_EQUAL_INT(0,
			      cogw_config_load_string(&next, CFG1(""), "next", err, sizeof(err)));
	TEST_ASSERT_FALSE(cogw_config_reload_check(&cfg, &next, NULL, 0));
	TEST_ASSERT_FALSE(cogw_config_reload_check(&cfg, &next, what, sizeof(what)));
	TEST_ASSERT_EQUAL_STRING("lines (count): needs a restart", what);
	cogw_config_free(&next);
}

/* ---- files ------------------------------------------------------------------------------ */

static void test_load_file(void)
{
	char path[] = "/tmp/cogw-test-config-XXXXXX";
	int fd = mkstemp(path);
	const char *text = "{\n  \"lines\": [\n    " LINE(", \"node_id\": 3") "\n  ]\n}\n";

	TEST_ASSERT_TRUE(fd >= 0);
	TEST_ASSERT_EQUAL_INT((int)strlen(text), (int)write(fd, text, strlen(text)));
	close(fd);
	TEST_ASSERT_EQUAL_INT(-EINVAL, cogw_config_load_file(&cfg, path, err, sizeof(err)));
	{
		char want[256];

		snprintf(want, sizeof(want), "%s: lines[0].node_id: duplicate key", path);
		TEST_ASSERT_EQUAL_STRING(want, err);
	}
	unlink(path);
	TEST_ASSERT_EQUAL_INT(-ENOENT, cogw_config_load_file(&cfg, path, err, sizeof(err)));
	{
		char want[256];

		snprintf(want, sizeof(want), "%s: cannot open: No such file or directory", path);
		TEST_ASSERT_EQUAL_STRING(want, err);
	}
	TEST_ASSERT_EQUAL_INT(0, cogw_config_load_file(&cfg, "etc/cogw.json", err, sizeof(err)));
	TEST_ASSERT_EQUAL_STRING("etc/cogw.json", cfg.source);
	TEST_ASSERT_EQUAL_size_t(3, cfg.n_lines);
}

/* The JSON OD builder alone, as cosim uses it. */
static void test_json_od_standalone(void)
{
	co_od *od = NULL;
	cJSON *objs = cJSON_Parse(
		"[{\"index\": \"0x6000\", \"object\": \"ARRAY\", \"type\": \"UNSIGNED8\","
		" \"length\": 2, \"default\": 9, \"access\": \"rwr\"}]");
	cJSON *vals = cJSON_Parse("[{\"index\": 24576, \"sub\": 2, \"value\": 3}]");

	TEST_ASSERT_EQUAL_INT(0, co_od_create(&od, 8));
	TEST_ASSERT_EQUAL_INT(0, json_od_add_objects(od, objs, "objects", err, sizeof(err)));
	TEST_ASSERT_EQUAL_INT(0, json_od_apply_values(od, vals, "values", err, sizeof(err)));
	TEST_ASSERT_EQUAL_HEX64(2, raw(od, 0x6000, 0));
	TEST_ASSERT_EQUAL_HEX64(9, raw(od, 0x6000, 1));
	TEST_ASSERT_EQUAL_HEX64(3, raw(od, 0x6000, 2));
	TEST_ASSERT_EQUAL_INT(-EINVAL,
			      json_od_add_objects(od, objs, "dev.objects", err, sizeof(err)));
	TEST_ASSERT_EQUAL_STRING("dev.objects[0].index: object 0x6000 already exists (a standard "
				 "object or defined twice; set values in \"values\")",
				 err);
	cJSON_Delete(objs);
	cJSON_Delete(vals);
	co_od_destroy(od);
}

/* ---- the CiA 302-7 gateway --------------------------------------------------------------- */

#define LINE_N(i, net)              \
	"{\"interface\": \"vcan" #i \
	"\", \"bitrate\": 500000, \"node_id\": 5, \"network_id\": " #net "}"
#define CFG3(gw) "{" gw "\"lines\": [" LINE_N(0, 7) ", " LINE_N(1, 3) ", " LINE_N(2, 9) "]}"

static void test_gateway_routes_and_network_ids(void)
{
	load_ok(CFG3("\"gateway\": {\"routes\": [{\"network\": 40, \"line\": 2, \"router\": 33}],"
		     " \"process_image\": [{\"index\": \"0xB000\", \"type\": \"INTEGER64\","
		     " \"access\": \"rw\", \"pdo\": true}, {\"index\": \"0xB001\","
		     " \"object\": \"ARRAY\", \"type\": \"UNSIGNED8\", \"access\": \"rw\","
		     " \"pdo\": true, \"length\": 2}]},"));
	for (size_t i = 0; i < 3; i++) {
		co_od *od = cfg.lines[i].od;
		/* every line routes to every line's network, and to 40 via node 33 */
		TEST_ASSERT_EQUAL_HEX64(0x01, raw(od, 0x1F2C, 7));
		TEST_ASSERT_EQUAL_HEX64(0x02, raw(od, 0x1F2C, 3));
		TEST_ASSERT_EQUAL_HEX64(0x03, raw(od, 0x1F2C, 9));
		TEST_ASSERT_EQUAL_HEX64(0x2103, raw(od, 0x1F2C, 40));
		TEST_ASSERT_EQUAL_HEX64(0, raw(od, 0x1F2C, 1));
		TEST_ASSERT_EQUAL_HEX64(cfg.lines[i].network_id, raw(od, 0x5F00, 0));
		/* the same process image on every line */
		TEST_ASSERT_NOT_NULL(co_od_find(od, 0xB000, 0));
		TEST_ASSERT_NOT_NULL(co_od_find(od, 0xB001, 2));
	}
	/* a line's values may still override its own table */
	cogw_config_free(&cfg);
	load_ok("{\"lines\": [" LINE_N(0, 1) ", {\"interface\": \"vcan1\", \"bitrate\": 500000,"
					     " \"node_id\": 5, \"values\": [{\"index\": "
					     "\"0x1F2C\", \"sub\": 1, \"value\": 0}]}]}");
	TEST_ASSERT_EQUAL_HEX64(0x01, raw(cfg.lines[0].od, 0x1F2C, 1));
	TEST_ASSERT_EQUAL_HEX64(0x02, raw(cfg.lines[0].od, 0x1F2C, 2));
	TEST_ASSERT_EQUAL_HEX64(0, raw(cfg.lines[1].od, 0x1F2C, 1));
}

/* 1F2Ch in "values" is checked as an SDO or mailbox write checks it, and
 * what would be two routes for one network is refused with its path. */
static void test_gateway_route_values_checked_as_at_run_time(void)
{
	char want[256], *big;
	size_t n = 0, cap = 64 * 1024;

	snprintf(want, sizeof want,
		 "t.json: lines[0].values[0].value: 65537 refused for 0x1F2C:28 (%s)",
		 sdo_abort_to_string(SDO_AB_VALUE));
	expect_error("{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 5,"
		     " \"values\": [{\"index\": \"0x1F2C\", \"sub\": 40, \"value\": 65537}]}]}",
		     want); /* bits 16..31 set */
	snprintf(want, sizeof want,
		 "t.json: lines[0].values[0].value: 4 refused for 0x1F2C:28 (%s)",
		 sdo_abort_to_string(SDO_AB_VALUE));
	expect_error("{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 5,"
		     " \"values\": [{\"index\": \"0x1F2C\", \"sub\": 40, \"value\": 4}]},"
		     " {\"interface\": \"vcan1\", \"bitrate\": 500000, \"node_id\": 5}]}",
		     want); /* line 4 of 2 */
	expect_error("{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 5,"
		     " \"network_id\": 7, \"values\": [{\"index\": \"0x1F2C\", \"sub\": 3,"
		     " \"value\": 1}]}, " LINE_N(1, 3) "]}",
		     "t.json: lines[0].values: 0x1F2C:03 = 0x00000001: network 3 is attached to "
		     "lines[1], its only route");
	expect_error(CFG3("\"gateway\": {\"routes\": [{\"network\": 40, \"line\": 2, \"router\": "
			  "33}, {\"network\": 40, \"line\": 0, \"router\": 2}]},"),
		     "t.json: gateway.routes[1].network: network 40 has a route already "
		     "(gateway.routes[0])");
	/* a route within the rules still loads, a network switched off too */
	load_ok("{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 5,"
		" \"values\": [{\"index\": \"0x1F2C\", \"sub\": 40, \"value\": \"0x2101\"},"
		" {\"index\": \"0x1F2C\", \"sub\": 2, \"value\": 0}]},"
		" {\"interface\": \"vcan1\", \"bitrate\": 500000, \"node_id\": 5}]}");
	TEST_ASSERT_EQUAL_HEX64(0x2101, raw(cfg.lines[0].od, 0x1F2C, 40));
	cogw_config_free(&cfg);

	/* absurd counts are refused before they are worked through */
	big = malloc(cap);
	TEST_ASSERT_NOT_NULL(big);
	n += (size_t)snprintf(big + n, cap - n, "{\"gateway\": {\"routes\": [");
	for (unsigned i = 0; i < 200; i++)
		n += (size_t)snprintf(big + n, cap - n,
				      "%s{\"network\": 40, \"line\": 0, \"router\": 2}",
				      i ? "," : "");
	n += (size_t)snprintf(big + n, cap - n, "]}, \"lines\": [" LINE_N(0, 1) "]}");
	TEST_ASSERT_LESS_THAN_size_t(cap, n);
	expect_error(big, "t.json: gateway.routes: 200 routes, at most 127 (one per network)");
	n = (size_t)snprintf(big, cap,
			     "{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": "
			     "500000, \"node_id\": 5, \"values\": [");
	for (unsigned i = 0; i < 2000; i++)
		n += (size_t)snprintf(big + n, cap - n, "%s{\"index\": \"0x1017\", \"value\": 1}",
				      i ? "," : "");
	n += (size_t)snprintf(big + n, cap - n, "]}]}");
	TEST_ASSERT_LESS_THAN_size_t(cap, n);
	TEST_ASSERT_EQUAL_INT(-EINVAL,
			      cogw_config_load_string(&cfg, big, "t.json", err, sizeof err));
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(err, "t.json: lines[0].values: 2000 values, more than "
						 "the "),
				     err);
	free(big);
}

static void test_gateway_errors(void)
{
	expect_error(
		CFG3("\"gateway\": {\"routes\": [{\"network\": 3, \"line\": 0, \"router\": 2}]},"),
		"t.json: gateway.routes[0]: network 3 is attached to lines[1]: it needs no route");
	expect_error(
		CFG3("\"gateway\": {\"routes\": [{\"network\": 4, \"line\": 0}]},"),
		"t.json: gateway.routes[0]: network 4 is not attached here: name its next router");
	expect_error(
		CFG3("\"gateway\": {\"routes\": [{\"network\": 4, \"line\": 3, \"router\": 2}]},"),
		"t.json: gateway.routes[0].line: line 3 does not exist (3 lines)");
	expect_error(CFG3("\"gateway\": {\"routes\": [{\"network\": 128, \"line\": 0, \"router\": "
			  "2}]},"),
		     "t.json: gateway.routes[0].network: 128 is out of range 1..127");
	expect_error(CFG3("\"gateway\": {\"route\": []},"),
		     "t.json: gateway.route: unknown key (did you mean \"routes\"?)");
	expect_error(CFG3("\"gateway\": {\"process_image\": [{\"index\": \"0xA000\", \"type\": "
			  "\"UNSIGNED8\","
			  " \"pdo\": true}]},"),
		     "t.json: gateway.process_image: A000h is outside B000h..BFFFh");
	expect_error(
		CFG3("\"gateway\": {\"process_image\": [{\"index\": \"0xB000\","
		     " \"type\": \"VISIBLE_STRING\", \"max_size\": 8, \"pdo\": true}]},"),
		"t.json: gateway.process_image: B000h:00: a VISIBLE_STRING cannot be forwarded "
		"by PDO (numeric types of at most 8 bytes)");
	expect_error(
		CFG3("\"gateway\": {\"process_image\": [{\"index\": \"0xB000\","
		     " \"type\": \"UNSIGNED8\"}]},"),
		"t.json: gateway.process_image: B000h:00 is not PDO-mappable (set \"pdo\": true)");
	expect_error(CFG1(", \"objects\": [{\"index\": \"0xB010\", \"type\": \"UNSIGNED8\"}]"),
		     "t.json: lines[0].objects[0]: B010h: B000h..BFFFh is the shared process image "
		     "of all lines: define it in gateway.process_image");
}

/* gateway.forward: two lines whose nodes 5 and 9 are mirrored */
#define FWD_LINE(i, node)                                                                   \
	"{\"interface\": \"vcan" #i "\", \"bitrate\": 500000, \"node_id\": 127, "           \
	"\"network_id\": " #i "1, \"rpdos\": 2, \"tpdos\": 2, \"manager\": {}, \"nodes\": " \
	"[{\"id\": " #node ", \"pdo\": \"auto\"}, {\"id\": 3}]}"
#define FWD_CFG(fwd)                        \
	"{\"gateway\": {\"forward\": [" fwd \
	"]}, \"lines\": [" FWD_LINE(0, 5) ", " FWD_LINE(1, 9) "]}"
#define FWD_END(line, node, index, sub) \
	"{\"line\": " #line ", \"node\": " #node ", \"index\": \"" index "\", \"sub\": " #sub "}"

static void test_gateway_forward(void)
{
	load_ok(FWD_CFG("{\"from\": " FWD_END(0, 5, "0x6000", 1) ", \"to\": " FWD_END(
		1, 9, "0x6200",
		1) "}, {\"from\": " FWD_END(1, 9, "0x6000",
					    2) ", \"to\": " FWD_END(0, 5, "0x6200",
								    2) ", \"image\": \"0xB123\"}"));
	TEST_ASSERT_EQUAL_size_t(2, cfg.n_forwards);
	const cogw_forward *f = &cfg.forwards[0];
	TEST_ASSERT_EQUAL_UINT8(0, f->from.line);
	TEST_ASSERT_EQUAL_UINT8(5, f->from.node);
	TEST_ASSERT_EQUAL_HEX16(0x6000, f->from.index);
	TEST_ASSERT_EQUAL_UINT8(1, f->from.sub);
	TEST_ASSERT_EQUAL_UINT8(1, f->to.line);
	TEST_ASSERT_EQUAL_UINT8(9, f->to.node);
	TEST_ASSERT_EQUAL_HEX16(0x6200, f->to.index);
	TEST_ASSERT_EQUAL_HEX16(COGW_FORWARD_IMAGE_FIRST, f->image);
	TEST_ASSERT_EQUAL_HEX16(0xB123, cfg.forwards[1].image);
	/* the image objects are on every line, UNSIGNED64, PDO-mappable both ways */
	for (size_t l = 0; l < cfg.n_lines; l++) {
		const co_od_entry *e = co_od_find(cfg.lines[l].od, COGW_FORWARD_IMAGE_FIRST, 0);
		TEST_ASSERT_NOT_NULL(e);
		TEST_ASSERT_EQUAL_UINT16(CO_T_UNSIGNED64, e->type);
		TEST_ASSERT_TRUE((e->access & CO_ACC_RPDO) && (e->access & CO_ACC_TPDO));
		TEST_ASSERT_NOT_NULL(co_od_find(cfg.lines[l].od, 0xB123, 0));
	}
}

static void test_gateway_forward_errors(void)
{
	expect_error(FWD_CFG("{\"from\": " FWD_END(0, 3, "0x6000",
						   1) ", \"to\": " FWD_END(1, 9, "0x6200", 1) "}"),
		     "t.json: gateway.forward[0].from: node 3 of line 0 is not mirrored: "
		     "forwarding needs it in that line's \"nodes\" with \"pdo\": \"auto\" "
		     "(docs/gateway.md)");
	expect_error(FWD_CFG("{\"from\": " FWD_END(0, 5, "0x6000",
						   1) ", \"to\": " FWD_END(0, 5, "0x6200", 1) "}"),
		     "t.json: gateway.forward[0]: from and to are on line 0: forwarding is "
		     "between lines");
	expect_error(FWD_CFG("{\"from\": " FWD_END(0, 5, "0x6000",
						   1) ", \"to\": " FWD_END(2, 9, "0x6200", 1) "}"),
		     "t.json: gateway.forward[0].to.line: 2 is out of range 0..1");
	expect_error(FWD_CFG("{\"from\": " FWD_END(0, 5, "0x6000", 1) ", \"to\": " FWD_END(
			     1, 9, "0x6200", 1) ", \"image\": \"0xA000\"}"),
		     "t.json: gateway.forward[0].image: A000h is outside the process image "
		     "B000h..BFFFh");
	expect_error(FWD_CFG("{\"from\": " FWD_END(0, 5, "0x6000", 1) ", \"to\": " FWD_END(
			     1, 9, "0x6200",
			     1) "}, {\"from\": " FWD_END(0, 5, "0x6000",
							 2) ", \"to\": " FWD_END(1, 9, "0x6200",
										 2) ", \"image\": "
										    "\"0xBF00\"}"),
		     "t.json: gateway.forward[1].image: BF00h is already an object of the process "
		     "image: give another \"image\"");
	expect_error(FWD_CFG("{\"from\": " FWD_END(0, 5, "0x6000", 1) ", \"to\": " FWD_END(
			     1, 9, "0x6200", 1) ", \"via\": 1}"),
		     "t.json: gateway.forward[0].via: unknown key");
	expect_error(FWD_CFG("{\"from\": " FWD_END(0, 5, "0x6000", 1) "}"),
		     "t.json: gateway.forward[0].to: required key is missing");
}

/* A FIFO at the config path made the loader (start-up, --check,
 * reload) wait for a writer for ever. alarm() turns a hang into a failure. */
static void test_fifo_config_refused_at_once(void)
{
	char dir[] = "/tmp/cogw-cfg-XXXXXX", path[64], msg[256];

	TEST_ASSERT_NOT_NULL(mkdtemp(dir));
	snprintf(path, sizeof path, "%s/fifo.json", dir);
	TEST_ASSERT_EQUAL_INT(0, mkfifo(path, 0600));
	alarm(10);
	int rc = cogw_config_load_file(&cfg, path, msg, sizeof msg);
	alarm(0);
	TEST_ASSERT_EQUAL_INT(-EIO, rc);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(msg, "not a regular file"), msg);
	unlink(path);
	rmdir(dir);
	/* a device too */
	alarm(10);
	rc = cogw_config_load_file(&cfg, "/dev/zero", msg, sizeof msg);
	alarm(0);
	TEST_ASSERT_EQUAL_INT(-EIO, rc);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_fifo_config_refused_at_once);
	RUN_TEST(test_embedded_default_parses);
	RUN_TEST(test_defaults_of_optional_keys);
	RUN_TEST(test_embedded_default_loads_from_any_directory);
	RUN_TEST(test_invalid_json_line_column);
	RUN_TEST(test_wrong_types);
	RUN_TEST(test_missing_required_keys);
	RUN_TEST(test_mailbox_limits_refused_with_path);
	RUN_TEST(test_out_of_range);
	RUN_TEST(test_unknown_keys);
	RUN_TEST(test_duplicate_lines);
	RUN_TEST(test_interface_and_names);
	RUN_TEST(test_bitrate_not_cia);
	RUN_TEST(test_too_many_lines_and_rules);
	RUN_TEST(test_access_rules);
	RUN_TEST(test_bad_object_definitions);
	RUN_TEST(test_app_objects);
	RUN_TEST(test_bad_values);
	RUN_TEST(test_od_typed_values);
	RUN_TEST(test_limits_enforced_after_load);
	RUN_TEST(test_values_update_structured_keys);
	RUN_TEST(test_sync_producer_and_pdos);
	RUN_TEST(test_reload_check);
	RUN_TEST(test_gateway_routes_and_network_ids);
	RUN_TEST(test_gateway_errors);
	RUN_TEST(test_gateway_route_values_checked_as_at_run_time);
	RUN_TEST(test_load_file);
	RUN_TEST(test_gateway_forward);
	RUN_TEST(test_gateway_forward_errors);
	RUN_TEST(test_json_od_standalone);
	return UNITY_END();
}
