/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/test_cosim_program.c - the simulated transducer's
 * program download objects (1F50h:1 flash, 1F51h:1 control, 1F56h:1
 * software identification) and its 1020h, driven through the real daemon
 * and cogwctl on vcan: the factory image running at power-on, a 64 KiB
 * image downloaded by block transfer after stop and clear, then started
 * (its CRC-32 checked by the device and shown in 1F56h:1) and kept across
 * an NMT reset; downloads refused while running or before a clear; a
 * corrupted image refused on start; a device without a factory image
 * (cleared flash) and the boot's program state check on both; a saved
 * program across power cycles (--nv), 1011h leaving it alone; 1020h written and read back; etc/transducer.dcf's
 * concise DCF accepted by the device entry by entry; cogwctl program, the
 * software manager of the daemon's line 0 (MGR_PROGRAM), with progress,
 * verification and refusals.
 *
 *   make build/san/tests/integration/test_cosim_program build/san/bin/cogwd \
 *        build/san/bin/cosim build/san/bin/cogwctl
 *   tests/vcan/run -n 3 -- build/san/tests/integration/test_cosim_program
 */
#include <cjson/cJSON.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/cdcf.h"
#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"
#include "unity.h"

#define CTL "build/san/bin/cogwctl"
#define IMAGE_SIZE (64u * 1024u)

static daemon_run dmn;
static cosim_run sim;

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
	snprintf(cmd, sizeof cmd, "%s --timeout 60000 %s >%s 2>%s", CTL, args, out_path, err_path);
	int st = system(cmd);
	res.exit = (st != -1 && WIFEXITED(st)) ? WEXITSTATUS(st) : -1;
	slurp(out_path, res.out, sizeof res.out);
	slurp(err_path, res.err, sizeof res.err);
	return &res;
}

/* An independent CRC-32 (IEEE 802.3) to build images with. */
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

static uint32_t write_image(const char *name, bool corrupt, char *path, size_t cap)
{
	static uint8_t img[IMAGE_SIZE];
	for (uint32_t i = 0; i < IMAGE_SIZE - 4; i++)
		img[i] = (uint8_t)(i * 131u + (i >> 8));
	uint32_t crc = crc32_ieee(img, IMAGE_SIZE - 4);
	for (int b = 0; b < 4; b++)
		img[IMAGE_SIZE - 4 + b] = (uint8_t)(crc >> (8 * b));
	if (corrupt)
		img[1000] ^= 0x40;
	snprintf(path, cap, "%s/%s", dmn.dir, name);
	FILE *f = fopen(path, "wb");
	TEST_ASSERT_NOT_NULL(f);
	TEST_ASSERT_EQUAL_size_t(IMAGE_SIZE, fwrite(img, 1, IMAGE_SIZE, f));
	fclose(f);
	return crc;
}

/* docs/cosim.md "Program download": the factory image is the text
 * "cosim factory image <1008h> <100Ah>" followed by its CRC-32. */
static uint32_t transducer_factory_id(void)
{
	static const char text[] = "cosim factory image STI-SIM 0001";
	return crc32_ieee((const uint8_t *)text, sizeof text - 1);
}

static double read_value(const char *obj, const char *sub, const char *type)
{
	ctl_run("--json sdo read 0 1 %s %s %s", obj, sub, type);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	cJSON *o = cJSON_Parse(res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(o, res.out);
	cJSON *v = cJSON_GetObjectItem(o, "value");
	TEST_ASSERT_NOT_NULL_MESSAGE(v, res.out);
	double d = v->valuedouble;
	cJSON_Delete(o);
	return d;
}

/* Line 0 has a manager (its software manager serves cogwctl program) that
 * boots no node of its own: the tests drive node 1 themselves. Line 1 has
 * none. */
static const char config[] =
	"{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 127,"
	" \"sdo_clients\": 4, \"manager\": {\"sdo_timeout_ms\": 2000}, \"nodes\": []},"
	" {\"interface\": \"vcan1\", \"bitrate\": 500000, \"node_id\": 127},"
	" {\"interface\": \"vcan2\", \"bitrate\": 500000, \"node_id\": 127}]}";

void setUp(void)
{
	memset(&dmn, 0, sizeof dmn);
	memset(&sim, 0, sizeof sim);
	TEST_ASSERT_EQUAL_INT(
		0, daemon_start(&dmn, &(daemon_opts){ .config_json = config, .n_lines = 3 }));
	const char *devices[] = { "etc/devices/sti-pressure.json", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim, dmn.dir, 0, devices, NULL));
}

/* a cogwctl running beside the test; tearDown stops it, so that it holds
 * no queues (and no RLIMIT_MSGQUEUE bytes) into the tests that follow */
static pid_t background_pid = -1;

void tearDown(void)
{
	if (background_pid > 0)
		proc_stop(background_pid, SIGTERM, 3000);
	background_pid = -1;
	cosim_stop(&sim, 3000);
	daemon_cleanup(&dmn);
	daemon_unlink_queues("main");
}

static void test_program_download_start_and_refusals(void)
{
	char good[200], bad[200];
	uint32_t crc = write_image("good.bin", false, good, sizeof good);
	write_image("bad.bin", true, bad, sizeof bad);

	/* a fresh device runs its factory image */
	TEST_ASSERT_EQUAL_DOUBLE(1, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE((double)transducer_factory_id(), read_value("1F56", "1", "u32"));

	/* no download while running, no clear while running */
	ctl_run("sdo write 0 1 1F50 1 domain @%s --mode block", good);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "08000022"), res.err);
	ctl_run("sdo write 0 1 1F51 1 u8 3");
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "08000022"), res.err);

	/* stop, and a download before the clear is refused too */
	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 1F51 1 u8 0")->exit);
	TEST_ASSERT_EQUAL_DOUBLE(0, read_value("1F51", "1", "u8"));
	ctl_run("sdo write 0 1 1F50 1 domain @%s --mode block", good);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "08000022"), res.err);

	/* clear: no software any more */
	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 1F51 1 u8 3")->exit);
	TEST_ASSERT_EQUAL_DOUBLE(3, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE(0, read_value("1F56", "1", "u32"));

	/* 64 KiB by block transfer */
	ctl_run("sdo write 0 1 1F50 1 domain @%s --mode block", good);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	TEST_ASSERT_EQUAL_DOUBLE(0, read_value("1F51", "1", "u8")); /* stopped */

	/* start: the device checks the CRC and runs it */
	ctl_run("sdo write 0 1 1F51 1 u8 1");
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	TEST_ASSERT_EQUAL_DOUBLE(1, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE((double)crc, read_value("1F56", "1", "u32"));

	/* the flash is no parameter: an NMT reset keeps the new program */
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "nmt reset-node", NULL, 0, 3000));
	TEST_ASSERT_EQUAL_DOUBLE(1, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE((double)crc, read_value("1F56", "1", "u32"));

	/* stop, clear, download a corrupted image: refused on start */
	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 1F51 1 u8 0")->exit);
	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 1F51 1 u8 3")->exit);
	TEST_ASSERT_EQUAL_DOUBLE(3, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE(0, read_value("1F56", "1", "u32"));
	ctl_run("sdo write 0 1 1F50 1 domain @%s --mode block", bad);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	ctl_run("sdo write 0 1 1F51 1 u8 1");
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "08000020"), res.err);
	TEST_ASSERT_EQUAL_DOUBLE(0, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE(0, read_value("1F56", "1", "u32"));
	/* an unknown command */
	ctl_run("sdo write 0 1 1F51 1 u8 7");
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "06090030"), res.err);
}

/* cogwctl program: the daemon's software manager (MGR_PROGRAM) runs stop,
 * clear, 64 KiB block download with progress events, start and verify; a
 * refused image is status I with the step and abort; refusals up front. */
static void test_cogwctl_program(void)
{
	char good[200], bad[200], empty[200], bg_out[200];
	uint32_t crc = write_image("good.bin", false, good, sizeof good);
	write_image("bad.bin", true, bad, sizeof bad);

	/* the first update of a fresh device (over its factory image),
	 * verified against --expect */
	ctl_run("program 0 1 %s --expect 0x%08X", good, (unsigned)crc);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	/* a progress line about every 4 KiB (as the block transfer pulls data) */
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, " of 65536 bytes (6 %)"), res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, "download  65536 of 65536 bytes (100 %)"),
				     res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, "65536 bytes to 1F50:01 by block transfer"),
				     res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.out, "program updated and running"), res.out);
	TEST_ASSERT_EQUAL_DOUBLE(1, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE((double)crc, read_value("1F56", "1", "u32"));
	TEST_ASSERT_TRUE_MESSAGE(
		file_wait_contains(dmn.log_path, "node 1: program updated (65536 bytes)", 2000),
		"no 'program updated' line in the daemon log");

	/* again, over a running program (stopped and cleared first), --json:
	 * the progress events, the last with every byte */
	ctl_run("--json program 0 1 %s --expect %u", good, (unsigned)crc);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	cJSON *o = cJSON_Parse(res.out);
	TEST_ASSERT_NOT_NULL_MESSAGE(o, res.out);
	TEST_ASSERT_TRUE(cJSON_IsTrue(cJSON_GetObjectItem(o, "ok")));
	TEST_ASSERT_TRUE(cJSON_IsTrue(cJSON_GetObjectItem(o, "verified")));
	TEST_ASSERT_EQUAL_INT(65536, cJSON_GetObjectItem(o, "size")->valueint);
	cJSON *prog = cJSON_GetObjectItem(o, "progress");
	int n = cJSON_GetArraySize(prog);
	TEST_ASSERT_EQUAL_INT(16, n); /* one per 4 KiB step reached */
	TEST_ASSERT_EQUAL_INT(
		65536, cJSON_GetObjectItem(cJSON_GetArrayItem(prog, n - 1), "sent")->valueint);
	cJSON_Delete(o);

	/* the wrong identification expected: I at the verify */
	ctl_run("program 0 1 %s --expect 0x12345678", good);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "verify"), res.err);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "status I"), res.err);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "expected 0x12345678"), res.err);

	/* a corrupted image: the device refuses to start it -> I, 08000020 */
	ctl_run("program 0 1 %s", bad);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "status I"), res.err);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "start (1F51:01 = 1)"), res.err);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "08000020"), res.err);
	TEST_ASSERT_EQUAL_DOUBLE(0, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE(0, read_value("1F56", "1", "u32"));
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(dmn.log_path, "node 1: software I", 2000),
				 "no status I in the daemon log");

	/* one update of a node at a time: a second one while the first
	 * downloads is refused (busy), the first ends well. The device answers
	 * late while it lasts, so the first download is still under way when
	 * the second cogwctl has started, however fast the bus is. */
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "sdo delay 40", NULL, 0, 3000));
	snprintf(bg_out, sizeof bg_out, "%s/bg.out", dmn.dir);
	const char *bg_argv[] = { CTL, "--timeout", "60000", "program", "0", "1", good, NULL };
	background_pid = proc_spawn(bg_argv, bg_out, NULL);
	TEST_ASSERT_TRUE(background_pid > 0);
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(bg_out, "download  ", 20000),
				 "the first update shows no progress");
	ctl_run("program 0 1 %s", good);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "being updated already"), res.err);
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "sdo delay 0", NULL, 0, 3000));
	TEST_ASSERT_TRUE_MESSAGE(file_wait_contains(bg_out, "program updated and running", 30000),
				 "the first update did not end well");

	/* refusals before anything reaches the bus */
	TEST_ASSERT_EQUAL_INT(2, ctl_run("program 0 1")->exit);
	TEST_ASSERT_EQUAL_INT(2, ctl_run("program 0 1 %s --expect 0x1FFFFFFFF", good)->exit);
	TEST_ASSERT_EQUAL_INT(2, ctl_run("program 0 0 %s", good)->exit);
	TEST_ASSERT_EQUAL_INT(2, ctl_run("program 0 128 %s", good)->exit);
	TEST_ASSERT_EQUAL_INT(2, ctl_run("program 0 1 %s/no-such.bin", dmn.dir)->exit);
	ctl_run("program 0 1 %s", dmn.dir); /* a directory */
	TEST_ASSERT_EQUAL_INT(2, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "not a regular file"), res.err);
	snprintf(empty, sizeof empty, "%s/empty.bin", dmn.dir);
	FILE *f = fopen(empty, "wb");
	TEST_ASSERT_NOT_NULL(f);
	fclose(f);
	ctl_run("program 0 1 %s", empty);
	TEST_ASSERT_EQUAL_INT(2, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "not 0"), res.err);
	/* the daemon: its own node-ID, a line without a manager */
	ctl_run("program 0 127 %s", good);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "program update of node 127"), res.err);
	ctl_run("program 1 1 %s", good);
	TEST_ASSERT_EQUAL_INT(1, res.exit);
	TEST_ASSERT_NOT_NULL_MESSAGE(strstr(res.err, "no manager"), res.err);
	/* the device kept the good program of the background update */
	TEST_ASSERT_EQUAL_DOUBLE((double)crc, read_value("1F56", "1", "u32"));
}

static const char managed_node_1[] =
	"{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 127,"
	" \"sdo_clients\": 4, \"manager\": {\"sdo_timeout_ms\": 2000}, \"nodes\": "
	"[{\"id\": 1}]}]}";

/* The daemon, restarted to boot node 1 with no software_id configured:
 * the boot reads the program state (CiA 302-3) whatever it is. */
static void restart_daemon_managing_node_1(void)
{
	TEST_ASSERT_NOT_EQUAL(-1, daemon_stop(&dmn, 5000));
	daemon_cleanup(&dmn);
	daemon_unlink_queues("main");
	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = managed_node_1,
								    .n_lines = 1 }));
}

/* The transducer as shipped runs its factory program: its boot reports
 * no program that does not run. */
static void test_factory_program_boots_without_warning(void)
{
	restart_daemon_managing_node_1();
	if (!file_wait_contains(dmn.log_path, "node 1 booted", 20000)) {
		proc_dump_log(dmn.log_path, 40);
		TEST_FAIL_MESSAGE("node 1 was not booted");
	}
	TEST_ASSERT_FALSE_MESSAGE(file_contains(dmn.log_path, "does not run"),
				  "the factory program was reported as not running");
	TEST_ASSERT_EQUAL_DOUBLE(1, read_value("1F51", "1", "u8"));
}

/* A program download cut short by a restart: the device's program was
 * stopped and its flash cleared (1F51h:1 = 3), then cogwd went away; a
 * device file with "factory": false is that device. The restarted daemon
 * boots node 1 (which resets it: the flash stays cleared) and reports the
 * program state (a warning in the log, the software step's boot event
 * naming 1F51h:01 = 3). */
static void test_cut_download_seen_at_the_next_boot(void)
{
	char blank[200];
	snprintf(blank, sizeof blank, "%s/blank.json", dmn.dir);
	FILE *f = fopen(blank, "w");
	TEST_ASSERT_NOT_NULL(f);
	fputs("{\"name\": \"blank\", \"node_id\": 1, \"heartbeat_ms\": 1000,"
	      " \"program\": {\"factory\": false}}\n",
	      f);
	fclose(f);
	cosim_stop(&sim, 3000);
	const char *devices[] = { blank, NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim, dmn.dir, 0, devices, NULL));
	TEST_ASSERT_EQUAL_DOUBLE(3, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE(0, read_value("1F56", "1", "u32"));

	restart_daemon_managing_node_1();
	TEST_ASSERT_TRUE_MESSAGE(
		file_wait_contains(dmn.log_path,
				   "node 1: its program does not run (1F51h:1 = 3, no program)",
				   20000),
		"the program state was not reported");
	TEST_ASSERT_EQUAL_DOUBLE(3, read_value("1F51", "1", "u8"));
}

/* The flash across power cycles (cosim restarted with --nv): a downloaded
 * program that 1010h saved comes back running; 1011h "load" neither
 * touches it now (an NMT reset keeps it) nor lets it come back after the
 * next power cycle, which brings the factory image again. */
static void test_saved_program_survives_a_power_cycle(void)
{
	char good[200];
	const char *devices[] = { "etc/devices/sti-pressure.json", NULL };
	const char *nv[] = { "--nv", dmn.dir, NULL };
	uint32_t crc = write_image("good.bin", false, good, sizeof good);

	cosim_stop(&sim, 3000);
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim, dmn.dir, 0, devices, nv));
	ctl_run("program 0 1 %s --expect 0x%08X", good, (unsigned)crc);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 1010 1 u32 0x65766173")->exit); /* save */

	cosim_stop(&sim, 3000);
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim, dmn.dir, 0, devices, nv));
	TEST_ASSERT_EQUAL_DOUBLE(1, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE((double)crc, read_value("1F56", "1", "u32"));

	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 1011 1 u32 0x64616F6C")->exit); /* load */
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim, "nmt reset-node", NULL, 0, 3000));
	/* program reset (stop, start): the image in the flash is checked again */
	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 1F51 1 u8 2")->exit);
	TEST_ASSERT_EQUAL_DOUBLE(1, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE((double)crc, read_value("1F56", "1", "u32"));

	cosim_stop(&sim, 3000);
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim, dmn.dir, 0, devices, nv));
	TEST_ASSERT_EQUAL_DOUBLE(1, read_value("1F51", "1", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE((double)transducer_factory_id(), read_value("1F56", "1", "u32"));
}

static void test_verify_configuration_object(void)
{
	TEST_ASSERT_EQUAL_DOUBLE(0, read_value("1020", "1", "u32"));
	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 1020 1 u32 15000")->exit);
	TEST_ASSERT_EQUAL_INT(0, ctl_run("sdo write 0 1 1020 2 u32 3600000")->exit);
	TEST_ASSERT_EQUAL_DOUBLE(15000, read_value("1020", "1", "u32"));
	TEST_ASSERT_EQUAL_DOUBLE(3600000, read_value("1020", "2", "u32"));
}

/* etc/transducer.dcf fits the transducer: its concise DCF (cogwctl dcf
 * convert), written entry by entry in order as the configuration manager
 * does, is accepted by the device and read back. */
static void test_transducer_dcf_fits_the_device(void)
{
	char cdc[200];
	static uint8_t buf[4096];
	snprintf(cdc, sizeof cdc, "%s/transducer.cdc", dmn.dir);
	ctl_run("dcf convert etc/transducer.dcf --node 1 -o %s", cdc);
	TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, res.err);
	FILE *fp = fopen(cdc, "rb");
	TEST_ASSERT_NOT_NULL(fp);
	size_t n = fread(buf, 1, sizeof buf, fp);
	fclose(fp);
	co_cdcf_iter it;
	co_cdcf_entry e;
	TEST_ASSERT_EQUAL_INT(0, co_cdcf_iter_init(&it, buf, n, NULL));
	TEST_ASSERT_TRUE(it.count >= 5);
	while (co_cdcf_iter_next(&it, &e)) {
		char hex[64] = "", *p = hex;
		for (uint32_t i = 0; i < e.size && i < 16; i++)
			p += sprintf(p, "%02x", e.data[i]);
		ctl_run("sdo write 0 1 %04X %u hex %s", e.index, e.sub, hex);
		char what[160];
		snprintf(what, sizeof what, "entry %u %04X:%02X: %.100s", (unsigned)e.number,
			 e.index, e.sub, res.err);
		TEST_ASSERT_EQUAL_INT_MESSAGE(0, res.exit, what);
	}
	TEST_ASSERT_EQUAL_DOUBLE(500, read_value("1017", "0", "u16"));   /* heartbeat */
	TEST_ASSERT_EQUAL_DOUBLE(500, read_value("1800", "5", "u16"));   /* event timer */
	TEST_ASSERT_EQUAL_DOUBLE(0x181, read_value("1800", "1", "u32")); /* valid again */
	TEST_ASSERT_EQUAL_DOUBLE(1, read_value("1A00", "0", "u8"));
	TEST_ASSERT_EQUAL_DOUBLE(0x20030020, read_value("1A00", "1", "u32"));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_program_download_start_and_refusals);
	RUN_TEST(test_cogwctl_program);
	RUN_TEST(test_factory_program_boots_without_warning);
	RUN_TEST(test_cut_download_seen_at_the_next_boot);
	RUN_TEST(test_saved_program_survives_a_power_cycle);
	RUN_TEST(test_verify_configuration_object);
	RUN_TEST(test_transducer_dcf_fits_the_device);
	return UNITY_END();
}
