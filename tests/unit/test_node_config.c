/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_node_config.c - where a node's configuration comes from
 * (cogw.json "nodes[].config"): a JSON entry list, a DCF/EDS file, a
 * binary concise DCF; every error names the JSON path and, for files, the
 * file and line.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "unity.h"

#include "apps/common/config.h"
#include "apps/common/node_config.h"
#include "core/cdcf.h"
#include "core/od.h"

static cogw_config cfg;
static char err[600];
static char dir[64];

static void put_file(const char *name, const void *data, size_t len)
{
	char path[128];
	FILE *f;
	snprintf(path, sizeof path, "%s/%s", dir, name);
	f = fopen(path, "wb");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_size_t(len, fwrite(data, 1, len, f));
	fclose(f);
}

void setUp(void)
{
	memset(&cfg, 0, sizeof(cfg));
	err[0] = '\0';
	snprintf(dir, sizeof dir, "/tmp/test_node_config_XXXXXX");
	TEST_ASSERT_NOT_NULL(mkdtemp(dir));
}

void tearDown(void)
{
	char cmd[128];
	cogw_config_free(&cfg);
	snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
	TEST_ASSERT_EQUAL_INT(0, system(cmd));
}

#define NODES(nodes)                                                                    \
	"{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 1, " \
	"\"nodes\": " nodes "}]}"

/* Load the JSON as a file in dir, so relative paths resolve there. */
static int load(const char *json)
{
	char path[128];
	put_file("cogw.json", json, strlen(json));
	snprintf(path, sizeof path, "%s/cogw.json", dir);
	return cogw_config_load_file(&cfg, path, err, sizeof err);
}

static void expect_error(const char *json, const char *want_after_source)
{
	char want[700];
	snprintf(want, sizeof want, "%s/cogw.json: %s", dir, want_after_source);
	cogw_config_free(&cfg);
	TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, load(json), json);
	TEST_ASSERT_EQUAL_STRING(want, err);
	TEST_ASSERT_EQUAL_size_t(0, cfg.n_lines);
}

static void test_entries_become_a_concise_dcf(void)
{
	const char *j = NODES(
		"[{\"id\": 5, \"config\": {\"store\": true, \"date\": 15000, \"time\": 3600000,"
		" \"entries\": ["
		"{\"index\": \"0x1017\", \"type\": \"UNSIGNED16\", \"value\": 500},"
		"{\"index\": \"0x1800\", \"sub\": 2, \"type\": \"UNSIGNED8\", \"value\": 254},"
		"{\"index\": 8192, \"sub\": 1, \"type\": \"VISIBLE_STRING\", \"value\": \"ab\"}]}},"
		" {\"id\": 6}]");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, load(j), err);
	TEST_ASSERT_EQUAL_size_t(2, cfg.lines[0].n_nodes);
	const cogw_node *n = &cfg.lines[0].nodes[0];
	TEST_ASSERT_EQUAL_UINT8(5, n->id);
	TEST_ASSERT_EQUAL_INT(COGW_NODE_CONFIG_ENTRIES, n->config.source);
	TEST_ASSERT_TRUE(n->config.store);
	TEST_ASSERT_TRUE(n->config.verify);
	TEST_ASSERT_EQUAL_UINT32(15000, n->config.date);
	TEST_ASSERT_EQUAL_UINT32(3600000, n->config.time);
	TEST_ASSERT_EQUAL_UINT32(3, n->config.entries);
	static const uint8_t want[] = { 3,    0,    0,    0,    0x17, 0x10, 0, 2, 0,   0,
					0,    0xF4, 0x01, 0x00, 0x18, 2,    1, 0, 0,   0,
					0xFE, 0x00, 0x20, 1,    2,    0,    0, 0, 'a', 'b' };
	TEST_ASSERT_EQUAL_size_t(sizeof want, n->config.cdcf_len);
	TEST_ASSERT_EQUAL_MEMORY(want, n->config.cdcf, sizeof want);
	/* the line's OD carries it for the configuration manager: 1F22h:5 (also
	 * as default, so a reset communication keeps it), 1F26h:5, 1F27h:5 */
	co_od *od = cfg.lines[0].od;
	uint8_t back[64];
	uint32_t blen = 0, v = 0;
	TEST_ASSERT_EQUAL_INT(0, co_od_get_bytes(od, 0x1F22, 5, back, sizeof back, &blen));
	TEST_ASSERT_EQUAL_UINT32(sizeof want, blen);
	TEST_ASSERT_EQUAL_MEMORY(want, back, sizeof want);
	co_od_reset_range(od, 0x1000, 0x1FFF);
	TEST_ASSERT_EQUAL_INT(0, co_od_get_bytes(od, 0x1F22, 5, back, sizeof back, &blen));
	TEST_ASSERT_EQUAL_UINT32(sizeof want, blen);
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u32(od, 0x1F26, 5, &v));
	TEST_ASSERT_EQUAL_UINT32(15000, v);
	TEST_ASSERT_EQUAL_INT(0, co_od_get_u32(od, 0x1F27, 5, &v));
	TEST_ASSERT_EQUAL_UINT32(3600000, v);
	/* node 6 has no configuration, but a 1F22h:6 to write one into */
	const co_od_entry *e6 = co_od_find(od, 0x1F22, 6);
	TEST_ASSERT_NOT_NULL(e6);
	TEST_ASSERT_EQUAL_UINT32(0, e6->size);
	TEST_ASSERT_TRUE(e6->max_size >= 16384);
	TEST_ASSERT_NULL(co_od_find(od, 0x1F22, 7));
	/* a node without "config" has nothing to download */
	TEST_ASSERT_EQUAL_UINT8(6, cfg.lines[0].nodes[1].id);
	TEST_ASSERT_EQUAL_INT(COGW_NODE_CONFIG_NONE, cfg.lines[0].nodes[1].config.source);
	TEST_ASSERT_NULL(cfg.lines[0].nodes[1].config.cdcf);
	/* reload: the same config is no change; another is */
	static cogw_config other;
	char what[256];
	TEST_ASSERT_TRUE(cogw_config_reload_check(&cfg, &cfg, what, sizeof what));
	char path[128];
	snprintf(path, sizeof path, "%s/cogw.json", dir);
	put_file("cogw.json", NODES("[{\"id\": 5}, {\"id\": 6}]"),
		 strlen(NODES("[{\"id\": 5}, {\"id\": 6}]")));
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, cogw_config_load_file(&other, path, err, sizeof err), err);
	/* a node's configuration is a node change (a reload's node diff); on
	 * a line without a manager nothing follows it at run time */
	TEST_ASSERT_TRUE(cogw_config_reload_check(&cfg, &other, what, sizeof what));
	static cogw_node_diff nd;
	const cogw_node *cur[128];
	cogw_nodes_by_id(&cfg.lines[0], cur);
	TEST_ASSERT_FALSE(cogw_config_node_diff(cur, &cfg.lines[0], &other.lines[0], 0, &nd));
	TEST_ASSERT_EQUAL_STRING("lines[0].nodes: needs a restart", nd.what);
	TEST_ASSERT_EQUAL_size_t(1, nd.n);
	TEST_ASSERT_EQUAL_UINT8(COGW_NODE_CHANGED, nd.change[0].kind);
	cogw_config_free(&other);
}

static void test_entry_errors_name_the_json_path(void)
{
	expect_error(NODES("[{\"id\": 5, \"config\": {\"entries\": [{\"index\": \"0x1017\", "
			   "\"type\": \"UNSIGNED8\", \"value\": 300}]}}]"),
		     "lines[0].nodes[0].config.entries[0].value: 300 is out of range 0..255");
	expect_error(NODES("[{\"id\": 5, \"config\": {\"entries\": [{\"index\": \"0x1017\", "
			   "\"type\": \"UINT8\", \"value\": 3}]}}]"),
		     "lines[0].nodes[0].config.entries[0].type: \"UINT8\" is not a CiA 301 data "
		     "type name (e.g. UNSIGNED16, VISIBLE_STRING)");
	expect_error(NODES("[{\"id\": 5, \"config\": {\"entries\": [{\"type\": \"UNSIGNED8\", "
			   "\"value\": 3}]}}]"),
		     "lines[0].nodes[0].config.entries[0].index: required key is missing");
	expect_error(NODES("[{\"id\": 5, \"config\": {\"entries\": [{\"index\": \"0x2000\", "
			   "\"sub\": 256, \"type\": \"UNSIGNED8\", \"value\": 3}]}}]"),
		     "lines[0].nodes[0].config.entries[0].sub: 256 is out of range 0..255");
	expect_error(NODES("[{\"id\": 5, \"config\": {\"entries\": [{\"index\": \"0x2000\", "
			   "\"type\": \"VISIBLE_STRING\", \"value\": \"\"}]}}]"),
		     "lines[0].nodes[0].config.entries[0].value: empty value (a concise DCF entry "
		     "needs at least one byte)");
	expect_error(
		NODES("[{\"id\": 5, \"config\": {\"entries\": {}}}]"),
		"lines[0].nodes[0].config.entries: expected an array of entries, got an object");
	expect_error(
		NODES("[{\"id\": 5, \"config\": {\"store\": true}}]"),
		"lines[0].nodes[0].config: one of \"entries\", \"dcf\" or \"concise\" is required");
	expect_error(NODES("[{\"id\": 5, \"config\": {\"entries\": [], \"dcf\": \"x.dcf\"}}]"),
		     "lines[0].nodes[0].config.dcf: only one of \"entries\", \"dcf\" and "
		     "\"concise\" (\"entries\" is given too)");
	expect_error(NODES("[{\"id\": 5, \"config\": {\"entries\": [], \"date\": 3}}]"),
		     "lines[0].nodes[0].config.time: \"date\" and \"time\" go together (the "
		     "expected 1020h:1/2)");
	expect_error(NODES("[{\"id\": 5, \"config\": {\"entries\": [], \"time\": 86400000, "
			   "\"date\": 1}}]"),
		     "lines[0].nodes[0].config.time: 86400000 is out of range 0..86399999");
	expect_error(NODES("[{\"id\": 1}]"), "lines[0].nodes[0].id: 1 is the line's own node_id");
	expect_error(NODES("[{\"id\": 5}, {\"id\": 5}]"),
		     "lines[0].nodes[1].id: node 5 is already in lines[0].nodes[0]");
	expect_error(NODES("[{\"id\": 5, \"cfg\": {}}]"), "lines[0].nodes[0].cfg: unknown key");
	expect_error(NODES("{}"), "lines[0].nodes: expected an array of nodes, got an object");
}

static void test_dcf_file_relative_to_the_config(void)
{
	const char *dcf =
		"[DeviceComissioning]\nNodeID=9\n"
		"[1017]\nDataType=0x0006\nAccessType=rw\nDefaultValue=100\nParameterValue=250\n"
		"[1014]\nDataType=0x0007\nAccessType=rw\nDefaultValue=$NODEID+0x80\n";
	put_file("dev.dcf", dcf, strlen(dcf));
	TEST_ASSERT_EQUAL_INT_MESSAGE(
		0, load(NODES("[{\"id\": 7, \"config\": {\"dcf\": \"dev.dcf\"}}]")), err);
	const cogw_node_config *nc = &cfg.lines[0].nodes[0].config;
	TEST_ASSERT_EQUAL_INT(COGW_NODE_CONFIG_DCF, nc->source);
	TEST_ASSERT_EQUAL_UINT32(2, nc->entries);
	char want_file[128];
	snprintf(want_file, sizeof want_file, "%s/dev.dcf", dir);
	TEST_ASSERT_EQUAL_STRING(want_file, nc->file);
	/* $NODEID is the node's id from cogw.json (7), not the DCF's NodeID */
	static const uint8_t want[] = { 2, 0, 0, 0,    0x14, 0x10, 0, 4, 0, 0, 0,   0x87,
					0, 0, 0, 0x17, 0x10, 0,    2, 0, 0, 0, 250, 0 };
	TEST_ASSERT_EQUAL_size_t(sizeof want, nc->cdcf_len);
	TEST_ASSERT_EQUAL_MEMORY(want, nc->cdcf, sizeof want);

	/* a configured value that does not fit is refused (a default value
	 * would be left out with a warning: docs/config.md) */
	const char *bad = "[1017]\nDataType=0x0006\nAccessType=rw\nParameterValue=70000\n";
	put_file("bad.dcf", bad, strlen(bad));
	char want_err[300];
	snprintf(want_err, sizeof want_err,
		 "lines[0].nodes[0].config.dcf: %s/bad.dcf:4: ParameterValue '70000': out of range "
		 "for UNSIGNED16 (max 65535)",
		 dir);
	expect_error(NODES("[{\"id\": 7, \"config\": {\"dcf\": \"bad.dcf\"}}]"), want_err);
	snprintf(
		want_err, sizeof want_err,
		"lines[0].nodes[0].config.dcf: %s/none.dcf: cannot open: No such file or directory",
		dir);
	expect_error(NODES("[{\"id\": 7, \"config\": {\"dcf\": \"none.dcf\"}}]"), want_err);
}

static void test_concise_file(void)
{
	uint8_t buf[64];
	co_cdcf_writer w;
	uint16_t hb = 300;
	co_cdcf_writer_init(&w, buf, sizeof buf);
	co_cdcf_writer_add(&w, 0x1017, 0, &hb, 2);
	long n = co_cdcf_writer_finish(&w);
	put_file("dev.cdc", buf, (size_t)n);
	TEST_ASSERT_EQUAL_INT_MESSAGE(
		0, load(NODES("[{\"id\": 7, \"config\": {\"concise\": \"dev.cdc\"}}]")), err);
	const cogw_node_config *nc = &cfg.lines[0].nodes[0].config;
	TEST_ASSERT_EQUAL_INT(COGW_NODE_CONFIG_CONCISE, nc->source);
	TEST_ASSERT_EQUAL_UINT32(1, nc->entries);
	TEST_ASSERT_EQUAL_size_t((size_t)n, nc->cdcf_len);
	TEST_ASSERT_EQUAL_MEMORY(buf, nc->cdcf, (size_t)n);
	cogw_config_free(&cfg);

	put_file("cut.cdc", buf, (size_t)n - 1);
	char want_err[300];
	snprintf(want_err, sizeof want_err,
		 "lines[0].nodes[0].config.concise: %s/cut.cdc: not a concise DCF: entry 1 of 1 "
		 "(1017:00) at byte 11: data cut short (size 2, 1 bytes left)",
		 dir);
	expect_error(NODES("[{\"id\": 7, \"config\": {\"concise\": \"cut.cdc\"}}]"), want_err);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_entries_become_a_concise_dcf);
	RUN_TEST(test_entry_errors_name_the_json_path);
	RUN_TEST(test_dcf_file_relative_to_the_config);
	RUN_TEST(test_concise_file);
	return UNITY_END();
}
