/* SPDX-License-Identifier: MIT */
/*
 * cogw.json: the "manager" section of a line and the CiA 302-2 keys of
 * "nodes" fill 1F80h, 1F81h, 1F84h..1F89h and 1016h of the line's own OD
 * (as defaults); bad values are refused with their JSON path.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "apps/common/config.h"
#include "core/cdcf.h"
#include "core/manager.h"
#include "core/nmt.h"
#include "core/od.h"
#include "unity.h"

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

#define LINE(extra) "{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 5" extra "}"
#define CFG1(extra) "{\"lines\": [" LINE(extra) "]}"

static void expect_error(const char *json, const char *msg)
{
	int rc = cogw_config_load_string(&cfg, json, "t.json", err, sizeof(err));

	TEST_ASSERT_EQUAL_INT(-EINVAL, rc);
	TEST_ASSERT_EQUAL_STRING(msg, err);
	TEST_ASSERT_EQUAL_size_t(0, cfg.n_lines);
}

static void load_ok(const char *json)
{
	int rc = cogw_config_load_string(&cfg, json, "t.json", err, sizeof(err));

	TEST_ASSERT_EQUAL_STRING("", err);
	TEST_ASSERT_EQUAL_INT(0, rc);
}

static uint64_t raw(const co_od *od, uint16_t index, uint8_t sub)
{
	co_od_entry *e = co_od_find(od, index, sub);

	TEST_ASSERT_NOT_NULL_MESSAGE(e, "entry missing");
	return co_od_entry_raw(e);
}

static void test_no_manager_no_objects(void)
{
	load_ok(CFG1(""));
	TEST_ASSERT_FALSE(cfg.lines[0].manager.enabled);
	TEST_ASSERT_NULL(co_od_find(cfg.lines[0].od, 0x1F89, 0));
}

static void test_manager_defaults(void)
{
	load_ok(CFG1(", \"manager\": {}"));
	const cogw_manager_config *m = &cfg.lines[0].manager;
	TEST_ASSERT_TRUE(m->enabled);
	TEST_ASSERT_EQUAL_HEX32(CO_MGR_1F80_MASTER, m->nmt_startup);
	TEST_ASSERT_EQUAL_UINT32(1000, m->retry_ms);
	TEST_ASSERT_EQUAL_UINT32(0, m->scan_ms);
	TEST_ASSERT_EQUAL_HEX64(CO_MGR_1F80_MASTER, raw(cfg.lines[0].od, 0x1F80, 0));
	TEST_ASSERT_EQUAL_HEX64(0, raw(cfg.lines[0].od, 0x1F89, 0));
	TEST_ASSERT_NOT_NULL(co_od_find(cfg.lines[0].od, 0x1F82, 128));
	TEST_ASSERT_NOT_NULL(co_od_find(cfg.lines[0].od, 0x1F25, 128));
}

static void test_manager_bits_by_name(void)
{
	load_ok(CFG1(", \"manager\": {\"start_all\": true, \"self_start\": false, "
		     "\"start_slaves\": false, \"on_mandatory_error\": \"stop_all\", "
		     "\"boot_time_ms\": 5000, \"scan_ms\": 2000, \"retry_ms\": 500, "
		     "\"max_parallel\": 3, \"accept_remote_nmt\": true}"));
	uint32_t want = CO_MGR_1F80_MASTER | CO_MGR_1F80_START_ALL | CO_MGR_1F80_NO_SELF_START |
			CO_MGR_1F80_APP_STARTS_SLAVES | CO_MGR_1F80_STOP_ALL_ON_ERROR;
	TEST_ASSERT_EQUAL_HEX64(want, raw(cfg.lines[0].od, 0x1F80, 0));
	TEST_ASSERT_EQUAL_HEX64(5000, raw(cfg.lines[0].od, 0x1F89, 0));
	const cogw_manager_config *m = &cfg.lines[0].manager;
	TEST_ASSERT_EQUAL_UINT32(2000, m->scan_ms);
	TEST_ASSERT_EQUAL_UINT32(500, m->retry_ms);
	TEST_ASSERT_EQUAL_UINT8(3, m->max_parallel);
	TEST_ASSERT_TRUE(m->accept_remote_nmt);
	cogw_config_free(&cfg);
	load_ok(CFG1(", \"manager\": {\"master\": false, \"on_mandatory_error\": \"reset_all\"}"));
	TEST_ASSERT_EQUAL_HEX64(CO_MGR_1F80_RESET_ALL_ON_ERROR, raw(cfg.lines[0].od, 0x1F80, 0));
}

static void test_nodes_fill_assignment_identity_heartbeat(void)
{
	load_ok(CFG1(
		", \"manager\": {}, \"nodes\": ["
		"{\"id\": 2, \"mandatory\": true, \"heartbeat_ms\": 1500, "
		" \"vendor_id\": \"0x250\", \"product_code\": 4660, \"keep_op\": true},"
		"{\"id\": 3, \"keep_alive\": true, \"guard_time_ms\": 100, \"retry_factor\": 3,"
		" \"device_type\": \"0x00040194\", \"serial\": 99, \"state\": \"pre-operational\"},"
		"{\"id\": 4, \"boot\": false, \"state\": \"stopped\"}]"));
	const co_od *od = cfg.lines[0].od;
	TEST_ASSERT_EQUAL_HEX64(CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT | CO_MGR_1F81_MANDATORY,
				raw(od, 0x1F81, 2));
	TEST_ASSERT_EQUAL_HEX64(CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT | CO_MGR_1F81_KEEP_ALIVE |
					3u << 8 | 100u << 16,
				raw(od, 0x1F81, 3));
	TEST_ASSERT_EQUAL_HEX64(CO_MGR_1F81_SLAVE, raw(od, 0x1F81, 4));
	TEST_ASSERT_EQUAL_HEX64(0, raw(od, 0x1F81, 5));
	TEST_ASSERT_EQUAL_HEX64(0x250, raw(od, 0x1F85, 2));
	TEST_ASSERT_EQUAL_HEX64(4660, raw(od, 0x1F86, 2));
	TEST_ASSERT_EQUAL_HEX64(0, raw(od, 0x1F84, 2));
	TEST_ASSERT_EQUAL_HEX64(0x00040194, raw(od, 0x1F84, 3));
	TEST_ASSERT_EQUAL_HEX64(99, raw(od, 0x1F88, 3));
	/* a 1016h entry for node 2 */
	bool found = false;
	for (unsigned s = 1; s <= 127; s++)
		if (co_od_find(od, 0x1016, (uint8_t)s) &&
		    raw(od, 0x1016, (uint8_t)s) == (2u << 16 | 1500))
			found = true;
	TEST_ASSERT_TRUE(found);
	TEST_ASSERT_TRUE(cfg.lines[0].nodes[0].keep_op);
	TEST_ASSERT_FALSE(cfg.lines[0].nodes[1].keep_op);
	/* "state": operational unless said otherwise */
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_OPERATIONAL, cfg.lines[0].nodes[0].target_state);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_PRE_OPERATIONAL, cfg.lines[0].nodes[1].target_state);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_STOPPED, cfg.lines[0].nodes[2].target_state);
	/* defaults: a reset communication keeps them */
	co_od_entry *e = co_od_find(od, 0x1F81, 2);
	co_od_entry_set_raw(e, 0);
	co_od_entry_reset(e);
	TEST_ASSERT_EQUAL_HEX64(CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT | CO_MGR_1F81_MANDATORY,
				raw(od, 0x1F81, 2));
}

/* The software manager keys: 1F55h:n, 1F81h bits 5/6, the image read at
 * load time; bad combinations and files refused with their path. */
static void test_node_software_keys(void)
{
	const char *img = "/tmp/cogw-test-config-program.bin";
	FILE *f = fopen(img, "wb");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_size_t(5, fwrite("\x01\x02\x03\x04\x05", 1, 5, f));
	fclose(f);
	load_ok(CFG1(", \"manager\": {}, \"nodes\": ["
		     "{\"id\": 2, \"software_id\": \"0x12345678\", \"software_update\": true,"
		     " \"program\": \"/tmp/cogw-test-config-program.bin\"},"
		     "{\"id\": 3, \"software_id\": 7}]"));
	const co_od *od = cfg.lines[0].od;
	TEST_ASSERT_EQUAL_HEX64(CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT | CO_MGR_1F81_VERIFY_SW |
					CO_MGR_1F81_UPDATE_SW,
				raw(od, 0x1F81, 2));
	TEST_ASSERT_EQUAL_HEX64(CO_MGR_1F81_SLAVE | CO_MGR_1F81_BOOT | CO_MGR_1F81_VERIFY_SW,
				raw(od, 0x1F81, 3));
	TEST_ASSERT_EQUAL_HEX64(0x12345678, raw(od, 0x1F55, 2));
	TEST_ASSERT_EQUAL_HEX64(7, raw(od, 0x1F55, 3));
	TEST_ASSERT_EQUAL_size_t(5, cfg.lines[0].nodes[0].program_len);
	TEST_ASSERT_EQUAL_MEMORY("\x01\x02\x03\x04\x05", cfg.lines[0].nodes[0].program, 5);
	TEST_ASSERT_NULL(cfg.lines[0].nodes[1].program);
	cogw_config_free(&cfg);

	expect_error(CFG1(", \"nodes\": [{\"id\": 2, \"software_update\": true}]"),
		     "t.json: lines[0].nodes[0].software_update: \"software_update\": true, "
		     "\"program\" and a "
		     "non-zero \"software_id\" go together (node 2)");
	expect_error(
		CFG1(", \"nodes\": [{\"id\": 2, \"software_id\": 1,"
		     " \"program\": \"/tmp/cogw-test-config-program.bin\"}]"),
		"t.json: lines[0].nodes[0].program: \"software_update\": true, \"program\" and a "
		"non-zero \"software_id\" go together (node 2)");
	expect_error(CFG1(", \"nodes\": [{\"id\": 2, \"software_id\": 1, \"software_update\": true,"
			  " \"program\": \"/nonexistent/x.bin\"}]"),
		     "t.json: lines[0].nodes[0].program: /nonexistent/x.bin: cannot open: No such "
		     "file or directory");
	remove(img);
}

/* Every file the configuration names gets the configuration file's own
 * treatment: a FIFO (or a device) is refused at once, never opened for a
 * blocking read (docs/config.md "Files"). */
static void test_named_files_that_are_fifos_refused_at_once(void)
{
	char dir[] = "/tmp/cogw-test-fifo-XXXXXX", fifo[64], json[512];
	const char *const named[] = {
		"\"config\": {\"dcf\": \"%s\"}",
		"\"config\": {\"concise\": \"%s\"}",
		"\"software_id\": 1, \"software_update\": true, \"program\": \"%s\"",
	};
	TEST_ASSERT_NOT_NULL(mkdtemp(dir));
	snprintf(fifo, sizeof fifo, "%s/p.fifo", dir);
	TEST_ASSERT_EQUAL_INT(0, mkfifo(fifo, 0600));
	for (size_t i = 0; i < sizeof named / sizeof named[0]; i++) {
		char node[256];
		snprintf(node, sizeof node, named[i], fifo);
		snprintf(json, sizeof json, CFG1(", \"manager\": {}, \"nodes\": [{\"id\": 2, %s}]"),
			 node);
		alarm(10); /* a blocking open of the FIFO would wait for a writer */
		int rc = cogw_config_load_string(&cfg, json, "t.json", err, sizeof(err));
		alarm(0);
		TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, rc, json);
		TEST_ASSERT_NOT_NULL_MESSAGE(strstr(err, "lines[0].nodes[0]."), err);
		TEST_ASSERT_NOT_NULL_MESSAGE(strstr(err, "p.fifo: not a regular file"), err);
	}
	unlink(fifo);
	rmdir(dir);
}

static void write_image(const char *path, size_t len, uint8_t fill)
{
	FILE *f = fopen(path, "wb");
	TEST_ASSERT_NOT_NULL(f);
	for (size_t i = 0; i < len; i++)
		TEST_ASSERT_NOT_EQUAL(EOF, fputc((int)(uint8_t)(fill + i), f));
	TEST_ASSERT_EQUAL_INT(0, fclose(f));
}

/* 126 nodes on one line and 3 on another name one program image (under two
 * names): it is read once and held once, 1 MiB and not 129 MiB (which the
 * default file_memory of 64 MiB would refuse). */
static void test_program_image_read_once_for_all_nodes(void)
{
	char dir[] = "/tmp/cogw-test-image-XXXXXX", img[64], json[40000];
	size_t n = 0;
	TEST_ASSERT_NOT_NULL(mkdtemp(dir));
	snprintf(img, sizeof img, "%s/app.bin", dir);
	write_image(img, 1u << 20, 7);
	n += (size_t)snprintf(json + n, sizeof json - n,
			      "{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, "
			      "\"node_id\": 127, \"manager\": {}, \"nodes\": [");
	for (unsigned id = 1; id <= 126; id++)
		n += (size_t)snprintf(
			json + n, sizeof json - n,
			"%s{\"id\": %u, \"software_id\": 1, \"software_update\": true, "
			"\"program\": \"%s%s\"}",
			id > 1 ? "," : "", id, id % 2 ? dir : "/tmp/./",
			id % 2 ? "/app.bin" : img + 5);
	n += (size_t)snprintf(
		json + n, sizeof json - n,
		"]}, {\"interface\": \"vcan1\", \"bitrate\": 500000, \"node_id\": 127, "
		"\"manager\": {}, \"nodes\": [");
	for (unsigned id = 1; id <= 3; id++)
		n += (size_t)snprintf(
			json + n, sizeof json - n,
			"%s{\"id\": %u, \"software_id\": 1, \"software_update\": true, "
			"\"program\": \"%s\"}",
			id > 1 ? "," : "", id, img);
	n += (size_t)snprintf(json + n, sizeof json - n, "]}]}");
	TEST_ASSERT_LESS_THAN_size_t(sizeof json, n);
	load_ok(json);
	const uint8_t *first = cfg.lines[0].nodes[0].program;
	TEST_ASSERT_NOT_NULL(first);
	TEST_ASSERT_EQUAL_UINT8(7, first[0]);
	for (size_t i = 0; i < 126; i++)
		TEST_ASSERT_EQUAL_PTR(first, cfg.lines[0].nodes[i].program);
	for (size_t i = 0; i < 3; i++)
		TEST_ASSERT_EQUAL_PTR(first, cfg.lines[1].nodes[i].program);
	TEST_ASSERT_EQUAL_size_t(1u << 20, cfg.lines[1].nodes[2].program_len);
	TEST_ASSERT_EQUAL_UINT64(1u << 20, cfg.files.held);
	cogw_config_free(&cfg);
	unlink(img);
	rmdir(dir);
}

/* file_memory bounds what the named files hold together: the file that does
 * not fit is refused with its JSON path. */
static void test_file_memory_bounds_the_named_files(void)
{
	char dir[] = "/tmp/cogw-test-files-XXXXXX", a[64], b[64], json[1024], want[512];
	TEST_ASSERT_NOT_NULL(mkdtemp(dir));
	snprintf(a, sizeof a, "%s/a.bin", dir);
	snprintf(b, sizeof b, "%s/b.bin", dir);
	write_image(a, 5000, 1);
	write_image(b, 5000, 2);
	snprintf(json, sizeof json,
		 "{\"file_memory\": 8192, \"lines\": [" LINE(
			 ", \"manager\": {}, \"nodes\": ["
			 "{\"id\": 2, \"software_id\": 1, \"software_update\": true, \"program\": "
			 "\"%s\"},"
			 "{\"id\": 3, \"software_id\": 1, \"software_update\": true, \"program\": "
			 "\"%s\"},"
			 "{\"id\": 4, \"software_id\": 1, \"software_update\": true, \"program\": "
			 "\"%s\"}]") "]}",
		 a, a, b);
	snprintf(want, sizeof want,
		 "t.json: lines[0].nodes[2].program: %s: 5000 more bytes do not fit: the files "
		 "named before hold 5000 of file_memory 8192",
		 b);
	expect_error(json, want);
	expect_error("{\"file_memory\": 100, \"lines\": [" LINE("") "]}",
		     "t.json: file_memory: 100 is out of range 4096..4294967295");
	unlink(a);
	unlink(b);
	rmdir(dir);
}

static void test_bad_values_with_paths(void)
{
	expect_error(CFG1(", \"manager\": {\"on_mandatory_error\": \"panic\"}"),
		     "t.json: lines[0].manager.on_mandatory_error: \"panic\": expected \"node\", "
		     "\"reset_all\" or \"stop_all\"");
	expect_error(CFG1(", \"manager\": {\"boot_time\": 1}"),
		     "t.json: lines[0].manager.boot_time: unknown key");
	expect_error(CFG1(", \"manager\": {\"start_all\": 1}"),
		     "t.json: lines[0].manager.start_all: expected true or false, got a number");
	expect_error(CFG1(", \"manager\": {\"retry_ms\": 0}"),
		     "t.json: lines[0].manager.retry_ms: 0 is out of range 10..3600000");
	expect_error(CFG1(", \"nodes\": [{\"id\": 2, \"retry_factor\": 256}]"),
		     "t.json: lines[0].nodes[0].retry_factor: 256 is out of range 0..255");
	expect_error(CFG1(", \"nodes\": [{\"id\": 2, \"vendor_id\": \"0x1FFFFFFFF\"}]"),
		     "t.json: lines[0].nodes[0].vendor_id: \"0x1FFFFFFFF\" is out of range "
		     "0x0000..0xFFFFFFFF");
	expect_error(
		CFG1(", \"nodes\": [{\"id\": 2, \"heartbeat_ms\": 100, \"guard_time_ms\": 100}]"),
		"t.json: lines[0].nodes[0].guard_time_ms: node 2 has heartbeat_ms too: "
		"supervise it one way");
	expect_error(
		CFG1(", \"manager\": {}, \"heartbeat_consumers\": [{\"node_id\": 2, \"time_ms\": "
		     "500}], "
		     "\"nodes\": [{\"id\": 2, \"heartbeat_ms\": 100}]"),
		"t.json: lines[0].nodes[0].heartbeat_ms: node 2 is in heartbeat_consumers too");
	expect_error(CFG1(", \"nodes\": [{\"id\": 2, \"state\": \"running\"}]"),
		     "t.json: lines[0].nodes[0].state: \"running\": expected \"operational\", "
		     "\"pre-operational\" or \"stopped\"");
	expect_error(CFG1(", \"nodes\": [{\"id\": 2, \"mandatory\": \"yes\"}]"),
		     "t.json: lines[0].nodes[0].mandatory: expected true or false, got a string");
}

/* The default configuration (make demo runs on it): the managers of lines 0
 * and 1 know the two simulated devices (identity of the files in
 * etc/devices); the configuration for tests that start nodes by hand has
 * no manager. */
static void test_default_configuration(void)
{
	int rc = cogw_config_load_file(&cfg, "tests/integration/config/hand-started.json", err,
				       sizeof(err));
	TEST_ASSERT_EQUAL_STRING("", err);
	TEST_ASSERT_EQUAL_INT(0, rc);
	for (size_t i = 0; i < cfg.n_lines; i++)
		TEST_ASSERT_FALSE(cfg.lines[i].manager.enabled);
	cogw_config_free(&cfg);
	memset(&cfg, 0, sizeof(cfg));
	rc = cogw_config_load_file(&cfg, "etc/cogw.json", err, sizeof(err));
	TEST_ASSERT_EQUAL_STRING("", err);
	TEST_ASSERT_EQUAL_INT(0, rc);
	TEST_ASSERT_TRUE(cfg.lines[0].manager.enabled);
	TEST_ASSERT_TRUE(cfg.lines[1].manager.enabled);
	TEST_ASSERT_FALSE(cfg.lines[2].manager.enabled);
	TEST_ASSERT_EQUAL_HEX64(0x250, raw(cfg.lines[0].od, 0x1F85, 1));
	TEST_ASSERT_EQUAL_HEX64(0x1234, raw(cfg.lines[1].od, 0x1F85, 2));
	/* the transducer's configuration from etc/transducer.dcf (CiA 302-3),
	 * with the date/time its 1020h is compared with */
	const cogw_node_config *nc = &cfg.lines[0].nodes[0].config;
	TEST_ASSERT_EQUAL_STRING("etc/transducer.dcf", nc->file);
	TEST_ASSERT_TRUE(nc->entries >= 5);
	TEST_ASSERT_EQUAL_UINT64(15300, raw(cfg.lines[0].od, 0x1F26, 1));
	TEST_ASSERT_EQUAL_UINT64(43200000, raw(cfg.lines[0].od, 0x1F27, 1));
	co_cdcf_iter it;
	co_cdcf_entry e;
	bool heartbeat = false, event_timer = false;
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_iter_init(&it, nc->cdcf, nc->cdcf_len, NULL));
	while (co_cdcf_iter_next(&it, &e)) {
		heartbeat |= e.index == 0x1017 && e.sub == 0 && e.size == 2 && e.data[0] == 0xF4;
		event_timer |= e.index == 0x1800 && e.sub == 5 && e.size == 2 && e.data[0] == 0xF4;
	}
	TEST_ASSERT_TRUE_MESSAGE(heartbeat, "no 1017h = 500 in the concise DCF");
	TEST_ASSERT_TRUE_MESSAGE(event_timer, "no 1800h:5 = 500 in the concise DCF");
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_no_manager_no_objects);
	RUN_TEST(test_manager_defaults);
	RUN_TEST(test_manager_bits_by_name);
	RUN_TEST(test_nodes_fill_assignment_identity_heartbeat);
	RUN_TEST(test_node_software_keys);
	RUN_TEST(test_named_files_that_are_fifos_refused_at_once);
	RUN_TEST(test_program_image_read_once_for_all_nodes);
	RUN_TEST(test_file_memory_bounds_the_named_files);
	RUN_TEST(test_bad_values_with_paths);
	RUN_TEST(test_default_configuration);
	return UNITY_END();
}
