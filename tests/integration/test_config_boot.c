/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/test_config_boot.c - the CiA 302-3 configuration
 * download during the CiA 302-2 boot, with the real daemon, the simulated
 * transducer (cosim) and cogwctl on vcan:
 *  - a node whose "config" is etc/transducer.dcf is configured while it
 *    boots (heartbeat 500 ms, TPDO 1 event timer 500 ms, 1020h = the
 *    configured date/time) and then started;
 *  - a 20-entry concise DCF (heartbeat, TPDO 1 remapped, calibration
 *    parameters) downloaded during the boot and read back byte-exact, then
 *    stored by the device (1010h); on the next boot of the node the
 *    download is skipped because its 1020h matches 1F26h/1F27h;
 *  - a configuration whose entry 7 the device refuses stops the boot with
 *    J (logged, and in the boot event and the node's diagnostics with the
 *    entry number and index:sub) and the node is not started.
 *
 *   make build/san/tests/integration/test_config_boot build/san/bin/cogwd \
 *        build/san/bin/cosim build/san/bin/cogwctl
 *   tests/vcan/run -n 3 -- build/san/tests/integration/test_config_boot
 */
#include <signal.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cjson/cJSON.h>

#include "core/cdcf.h"
#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"
#include "unity.h"

#define CTL "build/san/bin/cogwctl"

static daemon_run dmn;
static cosim_run sim;
static char cfg[4096];

typedef struct ctl_result {
	int exit;
	char out[8192];
	char err[4096];
} ctl_result;

static ctl_result res;

static void slurp(const char *path, char *buf, size_t cap)
{
	buf[0] = '\0';
	FILE *f = fopen(path, "r");
	if (!f)
		return;
	size_t n = fread(buf, 1, cap - 1, f);
	buf[n] = '\0';
	fclose(f);
}

static ctl_result *ctl_run(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static ctl_result *ctl_run(const char *fmt, ...)
{
	char args[1024], cmd[1400], out_path[128], err_path[128];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(args, sizeof args, fmt, ap);
	va_end(ap);
	snprintf(out_path, sizeof out_path, "%s/ctl.out", dmn.dir);
	snprintf(err_path, sizeof err_path, "%s/ctl.err", dmn.dir);
	snprintf(cmd, sizeof cmd, "%s --timeout 10000 %s >%s 2>%s", CTL, args, out_path, err_path);
	int st = system(cmd);
	res.exit = (st != -1 && WIFEXITED(st)) ? WEXITSTATUS(st) : -1;
	slurp(out_path, res.out, sizeof res.out);
	slurp(err_path, res.err, sizeof res.err);
	return &res;
}

static double read_value(const char *obj, const char *sub, const char *type)
{
	ctl_run("--json sdo read 0 1 %s %s %s", obj, sub, type);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	cJSON *o = cJSON_Parse(res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(o, res.out);
	double d = cJSON_GetObjectItem(o, "value")->valuedouble;
	cJSON_Delete(o);
	return d;
}

/* Wait until the node table shows node 1 in `state`. */
static bool wait_state(const char *state, unsigned ms)
{
	char want[64];
	snprintf(want, sizeof want, "\"node\":1,\"nmt_state\":\"%s\"", state);
	for (uint64_t until = mono_ms() + ms; mono_ms() < until; sleep_ms(250))
		if (ctl_run("--json status 0")->exit == 0 && strstr(res.out, want))
			return true;
	return false;
}

/* A `cogwctl monitor` of line 0's boot and manager events, JSON to out_path;
 * tearDown stops it (left running, it would hold its queues, and so its
 * user's RLIMIT_MSGQUEUE, into the tests that follow). */
static pid_t monitor_pid = -1;

static void monitor_start(const char *out_path, const char *duration_s)
{
	const char *argv[] = { CTL,       "--json",       "monitor",    "--line",   "0",
			       "--class", "manager,boot", "--duration", duration_s, NULL };
	monitor_pid = proc_spawn(argv, out_path, NULL);
	TEST_ASSERT_TRUE_MESSAGE(monitor_pid > 0, "cannot start cogwctl monitor");
}

/* The daemon with node 1 configured by node_config; with mon, a monitor of
 * the boot and manager events (JSON, to the file mon) runs from before the
 * device is switched on. */
static void start_monitored(const char *node_config, char *mon, size_t cap)
{
	snprintf(cfg, sizeof cfg,
		 "{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 127,"
		 " \"sdo_clients\": 4,"
		 " \"manager\": {\"reset_wait_ms\": 3000, \"sdo_timeout_ms\": 2000},"
		 " \"nodes\": [{\"id\": 1, \"mandatory\": true, \"config\": %s}]},"
		 " {\"interface\": \"vcan1\", \"bitrate\": 500000, \"node_id\": 127},"
		 " {\"interface\": \"vcan2\", \"bitrate\": 500000, \"node_id\": 127}]}",
		 node_config);
	TEST_ASSERT_EQUAL_INT(
		0, daemon_start(&dmn, &(daemon_opts){ .config_json = cfg, .n_lines = 3 }));
	if (mon) {
		snprintf(mon, cap, "%s/monitor.out", dmn.dir);
		monitor_start(mon, "60");
		TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(mon, "watching", 5000), "no monitor");
	}
	const char *devices[] = { "etc/devices/sti-pressure.json", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim, dmn.dir, 0, devices, NULL));
}

static void start(const char *node_config)
{
	start_monitored(node_config, NULL, 0);
}

/* An independent CRC-32 (IEEE 802.3): the simulated device's software
 * identification of an image is the CRC of all but its last 4 bytes,
 * which must hold that CRC. */
static uint32_t crc32_ieee(const uint8_t *p, size_t n)
{
	uint32_t crc = 0xFFFFFFFFu;
	for (size_t i = 0; i < n; i++) {
		crc ^= p[i];
		for (int b = 0; b < 8; b++)
			crc = (crc & 1u) ? (crc >> 1) ^ 0xEDB88320u : crc >> 1;
	}
	return ~crc;
}

#define IMAGE_SIZE (64u * 1024u)

/* A 64 KiB image in the daemon's directory; returns its identification. */
static uint32_t write_image(const char *path, bool corrupt)
{
	static uint8_t img[IMAGE_SIZE];
	for (uint32_t i = 0; i < IMAGE_SIZE - 4; i++)
		img[i] = (uint8_t)(i * 13u + (i >> 9));
	uint32_t crc = crc32_ieee(img, IMAGE_SIZE - 4);
	for (int b = 0; b < 4; b++)
		img[IMAGE_SIZE - 4 + b] = (uint8_t)(crc >> (8 * b));
	if (corrupt)
		img[4242] ^= 0x10;
	FILE *f = fopen(path, "wb");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_size_t(IMAGE_SIZE, fwrite(img, 1, IMAGE_SIZE, f));
	fclose(f);
	return crc;
}

/* The daemon with node 1 under the software manager: its program from
 * `image` (written now, corrupted or not); a monitor of the manager's
 * events runs from before the device is switched on. */
static char image_path[128];

static uint32_t start_software(bool corrupt, char *mon_path, size_t cap)
{
	char node_cfg[600];
	uint32_t crc;
	snprintf(image_path, sizeof image_path, "/tmp/cogw-test-program-%d.bin", (int)getpid());
	crc = write_image(image_path, corrupt);
	snprintf(node_cfg, sizeof node_cfg,
		 "{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 127,"
		 " \"sdo_clients\": 4,"
		 " \"manager\": {\"reset_wait_ms\": 3000, \"sdo_timeout_ms\": 2000},"
		 " \"nodes\": [{\"id\": 1, \"mandatory\": true, \"software_id\": %u,"
		 " \"software_update\": true, \"program\": \"%s\"}]},"
		 " {\"interface\": \"vcan1\", \"bitrate\": 500000, \"node_id\": 127},"
		 " {\"interface\": \"vcan2\", \"bitrate\": 500000, \"node_id\": 127}]}",
		 (unsigned)(corrupt ? crc ^ 1u : crc), image_path);
	snprintf(cfg, sizeof cfg, "%s", node_cfg);
	TEST_ASSERT_EQUAL_INT(
		0, daemon_start(&dmn, &(daemon_opts){ .config_json = cfg, .n_lines = 3 }));
	snprintf(mon_path, cap, "%s/monitor.out", dmn.dir);
	monitor_start(mon_path, "40");
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(mon_path, "watching", 5000), "no monitor");
	const char *devices[] = { "etc/devices/sti-pressure.json", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim, dmn.dir, 0, devices, NULL));
	return crc;
}

/* Software manager during the boot: the fresh device's 1F56h:1 (the factory image's)
 * differs from software_id -> stop, clear, 64 KiB block download with
 * progress events, start, verify; then the node is started. */
static void test_program_updated_during_boot(void)
{
	char mon[200];
	uint32_t crc = start_software(false, mon, sizeof mon);
	if (!wait_state("operational", 40000)) {
		proc_dump_log(dmn.log_path, 40);
		TEST_FAIL_MESSAGE("node 1 was not started");
	}
	TEST_ASSERT_EQUAL_DOUBLE((double)crc, read_value("1F56", "1", "u32"));
	TEST_ASSERT_EQUAL_DOUBLE(1, read_value("1F51", "1", "u8")); /* running */
	TEST_ASSERT_TRUE_MESSAGE(
		file_wait_contains(dmn.log_path, "node 1: program updated (65536 bytes)", 5000),
		"no 'program updated' line in the daemon log");
	/* progress events on the mailbox: the last one has all bytes */
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(mon, "\"what\":\"program\"", 5000),
				 "no progress event");
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(mon, "\"value\":65536", 5000),
				 "no final progress event");
	unlink(image_path);
}

/* An image the device refuses to start: status I, the node not started. */
static void test_refused_image_is_i(void)
{
	char mon[200];
	(void)start_software(true, mon, sizeof mon);
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(dmn.log_path, "node 1: software I", 40000),
				 "no status I in the daemon log");
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(dmn.log_path, "1F51:01: abort 08000020", 1000),
				 "not refused by the start");
	TEST_ASSERT_FALSE(wait_state("operational", 3000));
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(mon, "\"status\":\"I\"", 5000),
				 "no boot event with I");
	unlink(image_path);
}

void setUp(void)
{
	memset(&dmn, 0, sizeof dmn);
	memset(&sim, 0, sizeof sim);
}

void tearDown(void)
{
	if (monitor_pid > 0)
		proc_stop(monitor_pid, SIGTERM, 3000);
	monitor_pid = -1;
	cosim_stop(&sim, 3000);
	daemon_cleanup(&dmn);
	daemon_unlink_queues("main");
}

static void test_dcf_downloaded_during_boot(void)
{
	char node_cfg[1200], cwd[900];
	TEST_ASSERT_NOT_NULL(getcwd(cwd, sizeof cwd));
	snprintf(node_cfg, sizeof node_cfg,
		 "{\"dcf\": \"%s/etc/transducer.dcf\", \"date\": 15000, \"time\": 1000}", cwd);
	start(node_cfg);
	if (!wait_state("operational", 30000)) {
		proc_dump_log(dmn.log_path, 40);
		TEST_FAIL_MESSAGE("node 1 was not started");
	}
	TEST_ASSERT_EQUAL_DOUBLE(500, read_value("1017", "0", "u16"));
	TEST_ASSERT_EQUAL_DOUBLE(500, read_value("1800", "5", "u16"));
	TEST_ASSERT_EQUAL_DOUBLE(0x181, read_value("1800", "1", "u32"));
	TEST_ASSERT_EQUAL_DOUBLE(15000, read_value("1020", "1", "u32"));
	TEST_ASSERT_EQUAL_DOUBLE(1000, read_value("1020", "2", "u32"));
	TEST_ASSERT_TRUE_MESSAGE(
		file_wait_contains(dmn.log_path, "node 1: configured (10 entries)", 5000),
		"no 'configured' line in the daemon log");

	/* cogwctl configure (1F25h): the device's configuration was changed
	 * behind the manager's back (1020h no longer matches): configured again */
	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 1017 0 u16 900")->exit);
	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 1020 1 u32 1")->exit);
	ctl_run("configure 0 1");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, "node 1"), res.out);
	bool back = false;
	for (uint64_t until = mono_ms() + 20000; !back && mono_ms() < until; sleep_ms(250))
		back = wait_state("operational", 1000) && read_value("1017", "0", "u16") == 500 &&
		       read_value("1020", "1", "u32") == 15000;
	TEST_ASSERT_TRUE_MESSAGE(back, "node 1 not configured again after cogwctl configure");
	ctl_run("--json configure 0 all");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, "\"node\":\"all\""), res.out);
	TEST_ASSERT_EQUAL_INT(2, ctl_run("configure 0 128")->exit);
	TEST_ASSERT_EQUAL_INT(2, ctl_run("configure 0")->exit);
	TEST_ASSERT_TRUE(wait_state("operational", 20000));

	/* a new configuration written into the manager's 1F22h:1 over the
	 * mailbox (with a new expected date, else 1020h would still match),
	 * then configured: downloaded; a value that is no concise DCF is
	 * refused */
	static const uint8_t hb650[] = { 0x01, 0, 0, 0, 0x17, 0x10, 0, 0x02, 0, 0, 0, 0x8A, 0x02 };
	char cdc[200];
	snprintf(cdc, sizeof cdc, "%s/hb650.cdc", dmn.dir);
	FILE *f = fopen(cdc, "wb");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_size_t(sizeof hb650, fwrite(hb650, 1, sizeof hb650, f));
	fclose(f);
	ctl_run("od write 0 1F22 1 domain 01000000171000");
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "06090030"), res.err);
	ctl_run("od write 0 1F22 1 domain @%s", cdc);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	TEST_ASSERT_EQUAL_INT(0, ctl_run("od write 0 1F26 1 u32 15001")->exit);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, ctl_run("configure 0 1")->exit, res.err);
	back = false;
	for (uint64_t until = mono_ms() + 20000; !back && mono_ms() < until; sleep_ms(250))
		back = wait_state("operational", 1000) && read_value("1017", "0", "u16") == 650 &&
		       read_value("1020", "1", "u32") == 15001;
	TEST_ASSERT_TRUE_MESSAGE(back, "1F22h:1 written over the mailbox was not downloaded");
	TEST_ASSERT_TRUE(file_wait_contains(dmn.log_path, "node 1: configured (1 entries)", 2000));
}

/* 20 entries as the transducer takes them: heartbeat, TPDO 1 disabled,
 * remapped to two objects and enabled again with new timing, 2000h:1..8,
 * 2004h:1, 2005h:1 (REAL32 calibration parameters). */
static const struct cfg_entry {
	uint16_t index;
	uint8_t sub;
	uint8_t size;
	uint8_t data[4];
} twenty[] = {
	{ 0x1017, 0, 2, { 0xBC, 0x02 } },             /* 700 ms */
	{ 0x1800, 1, 4, { 0x81, 0x01, 0x00, 0x80 } }, /* TPDO 1 off */
	{ 0x1A00, 0, 1, { 0 } },
	{ 0x1A00, 1, 4, { 0x20, 0x00, 0x03, 0x20 } }, /* 2003h, 32 bits */
	{ 0x1A00, 2, 4, { 0x20, 0x00, 0x03, 0x20 } }, /* twice: 8 bytes */
	{ 0x1A00, 0, 1, { 2 } },
	{ 0x1800, 2, 1, { 254 } },
	{ 0x1800, 3, 2, { 0xC8, 0x00 } },             /* inhibit 20 ms */
	{ 0x1800, 5, 2, { 0xEE, 0x02 } },             /* event 750 ms */
	{ 0x1800, 1, 4, { 0x81, 0x01, 0x00, 0x00 } }, /* TPDO 1 on */
	{ 0x2000, 1, 4, { 0x00, 0x00, 0xC8, 0x41 } }, /* 25.0 */
	{ 0x2000, 2, 4, { 0x00, 0x00, 0x80, 0x3F } },
	{ 0x2000, 3, 4, { 0x00, 0x00, 0x00, 0x40 } },
	{ 0x2000, 4, 4, { 0x00, 0x00, 0x40, 0x40 } },
	{ 0x2000, 5, 4, { 0x00, 0x00, 0x80, 0x40 } },
	{ 0x2000, 6, 4, { 0x00, 0x00, 0xA0, 0x40 } },
	{ 0x2000, 7, 4, { 0x00, 0x00, 0xC0, 0x40 } },
	{ 0x2000, 8, 4, { 0x00, 0x00, 0xE0, 0x40 } },
	{ 0x2004, 1, 4, { 0x00, 0x00, 0x00, 0x3F } }, /* zero offset 0.5 */
	{ 0x2005, 1, 4, { 0x00, 0x00, 0xC6, 0x42 } }, /* span 99.0 */
};
#define N_TWENTY (sizeof twenty / sizeof twenty[0])

/* The bytes node 1 holds in index:sub, as lowercase hex "xx xx ..". */
static void read_hex(uint16_t index, uint8_t sub, char *hex, size_t cap)
{
	ctl_run("--json sdo read 0 1 %04X %u", index, sub);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	cJSON *o = cJSON_Parse(res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(o, res.out);
	cJSON *h = cJSON_GetObjectItem(o, "hex");
	TEST_ASSERT_TRUE_MESSAGE(cJSON_IsString(h), res.out);
	snprintf(hex, cap, "%s", h->valuestring);
	cJSON_Delete(o);
}

static void test_twenty_entries_byte_exact_then_skipped_on_the_next_boot(void)
{
	static uint8_t cdc[1024];
	char path[128], node_cfg[300], mon[200];
	co_cdcf_writer w;

	co_cdcf_writer_init(&w, cdc, sizeof cdc);
	for (size_t i = 0; i < N_TWENTY; i++)
		co_cdcf_writer_add(&w, twenty[i].index, twenty[i].sub, twenty[i].data,
				   twenty[i].size);
	long len = co_cdcf_writer_finish(&w);
	TEST_ASSERT_TRUE(len > 0);
	TEST_ASSERT_EQUAL_UINT32(20, w.count);
	snprintf(path, sizeof path, "/tmp/cogw-test-twenty-%d.cdc", (int)getpid());
	FILE *f = fopen(path, "wb");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_size_t((size_t)len, fwrite(cdc, 1, (size_t)len, f));
	fclose(f);
	snprintf(node_cfg, sizeof node_cfg,
		 "{\"concise\": \"%s\", \"date\": 15100, \"time\": 7200000, \"store\": true}",
		 path);
	start_monitored(node_cfg, mon, sizeof mon);
	if (!wait_state("operational", 30000)) {
		proc_dump_log(dmn.log_path, 40);
		TEST_FAIL_MESSAGE("node 1 was not started");
	}
	TEST_ASSERT_TRUE_MESSAGE(
		file_wait_contains(dmn.log_path, "node 1: configured (20 entries)", 5000),
		"no 'configured (20 entries)' line in the daemon log");
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(mon, "\"step\":\"configure\"", 5000),
				 "no configure step in the boot events");

	/* byte-exact: the last write of each index:sub is what the node holds */
	for (size_t i = 0; i < N_TWENTY; i++) {
		size_t last = i;
		for (size_t k = i + 1; k < N_TWENTY; k++)
			if (twenty[k].index == twenty[i].index && twenty[k].sub == twenty[i].sub)
				last = k;
		if (last != i)
			continue;
		char want[16] = "", got[64], what[96];
		for (unsigned b = 0; b < twenty[i].size; b++)
			sprintf(want + strlen(want), "%s%02x", b ? " " : "", twenty[i].data[b]);
		read_hex(twenty[i].index, twenty[i].sub, got, sizeof got);
		snprintf(what, sizeof what, "entry %zu (%04X:%02X)", i + 1, twenty[i].index,
			 twenty[i].sub);
		TEST_ASSERT_EQUAL_STRING_MESSAGE(want, got, what);
	}
	TEST_ASSERT_EQUAL_DOUBLE(15100, read_value("1020", "1", "u32"));
	TEST_ASSERT_EQUAL_DOUBLE(7200000, read_value("1020", "2", "u32"));

	/* the next boot of the node: 1020h (stored by the device with the rest)
	 * matches, so nothing is downloaded - a parameter changed behind the
	 * manager's back keeps its value */
	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 2000 1 r32 30.5")->exit);
	TEST_ASSERT_EQUAL_INT(0, ctl_run("boot 0 1")->exit);
	TEST_ASSERT_TRUE_MESSAGE(
		file_wait_contains(dmn.log_path,
				   "node 1: configuration unchanged (1020h matches 1F26h/1F27h)",
				   30000),
		"the second boot did not skip the download");
	TEST_ASSERT_TRUE(wait_state("operational", 30000));
	TEST_ASSERT_EQUAL_DOUBLE(30.5, read_value("2000", "1", "r32"));
	char got[64];
	read_hex(0x1017, 0, got, sizeof got); /* stored: kept over the reset */
	TEST_ASSERT_EQUAL_STRING("bc 02", got);
	unlink(path);
}

static void test_abort_on_entry_7_is_j(void)
{
	char mon[200];
	start_monitored(
		"{\"entries\": ["
		"{\"index\": \"0x1017\", \"type\": \"UNSIGNED16\", \"value\": 700},"
		"{\"index\": \"0x2004\", \"sub\": 1, \"type\": \"REAL32\", \"value\": 0.5},"
		"{\"index\": \"0x2005\", \"sub\": 1, \"type\": \"REAL32\", \"value\": 99.0},"
		"{\"index\": \"0x1800\", \"sub\": 5, \"type\": \"UNSIGNED16\", \"value\": 800},"
		"{\"index\": \"0x2000\", \"sub\": 1, \"type\": \"REAL32\", \"value\": 1.0},"
		"{\"index\": \"0x2000\", \"sub\": 2, \"type\": \"REAL32\", \"value\": 2.0},"
		"{\"index\": \"0x1000\", \"type\": \"UNSIGNED32\", \"value\": 1},"
		"{\"index\": \"0x1017\", \"type\": \"UNSIGNED16\", \"value\": 900}]}",
		mon, sizeof mon);
	TEST_ASSERT_TRUE_MESSAGE(
		file_wait_contains(dmn.log_path,
				   "node 1: configuration failed at entry 7 (1000:00)", 30000),
		"no J for entry 7 in the daemon log");
	TEST_ASSERT_FALSE(wait_state("operational", 3000));
	TEST_ASSERT_EQUAL_DOUBLE(700, read_value("1017", "0", "u16")); /* entry 8 not written */
	TEST_ASSERT_EQUAL_DOUBLE(800, read_value("1800", "5", "u16"));
	/* the boot event on the mailbox: J with the entry and its index:sub */
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(mon, "\"status\":\"J\"", 5000),
				 "no boot event with J");
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(mon, "\"index\":4096,\"sub\":0", 1000),
				 "the J event does not name 1000:00");
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(mon, "\"entry\":7", 1000),
				 "the J event does not name entry 7");
	/* and the node's diagnostics */
	ctl_run("diag 0 1");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, "status J"), res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, "1000:00, entry 7"), res.out);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_dcf_downloaded_during_boot);
	RUN_TEST(test_twenty_entries_byte_exact_then_skipped_on_the_next_boot);
	RUN_TEST(test_abort_on_entry_7_is_j);
	RUN_TEST(test_program_updated_during_boot);
	RUN_TEST(test_refused_image_is_i);
	return UNITY_END();
}
