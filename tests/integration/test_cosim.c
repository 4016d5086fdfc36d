/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/test_cosim.c - the simulated STI pressure transducer
 * (apps/cosim + etc/devices/sti-pressure.json) against the golden frames of
 * the transducer (SDO V1-V9 and the derived extras, LSS L1-L15; docs/cosim.md),
 * its non-volatile memory, and every fault the control socket switches.
 *
 * Real processes on a real vcan line: cosim is fork/exec'ed, the test
 * talks raw SocketCAN. Run from the repo root:
 *   make build/san/bin/cosim build/san/tests/integration/test_cosim
 *   tests/vcan/run -n 3 -- build/san/tests/integration/test_cosim
 * Timeouts are generous: the VM that provides vcan is slow.
 */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <sys/un.h>
#include <unistd.h>

#include <linux/can.h>

#include "tests/integration/support/proc.h"
#include "unity.h"

#define COSIM "build/san/bin/cosim"
#define DEVICE "etc/devices/sti-pressure.json"
#define WAIT_MS 5000

static int can_fd = -1;
static pid_t sim = -1;
static char dir[64];
static char nv[96], ctl[96], log_path[96];

/* ---- helpers ------------------------------------------------------------------ */

static void drain(void)
{
	struct can_frame f;

	while (recv(can_fd, &f, sizeof f, MSG_DONTWAIT) > 0)
		;
}

static void start_sim(const char *extra)
{
	const char *argv[16];
	int n = 0;

	argv[n++] = COSIM;
	argv[n++] = "--interface";
	argv[n++] = "vcan0";
	argv[n++] = "--device";
	argv[n++] = DEVICE;
	argv[n++] = "--nv";
	argv[n++] = nv;
	argv[n++] = "--control";
	argv[n++] = ctl;
	if (extra)
		argv[n++] = extra;
	argv[n] = NULL;
	drain();
	sim = proc_spawn(argv, log_path, NULL);
	TEST_ASSERT_TRUE_MESSAGE(sim > 0, "cannot start " COSIM);
}

static void stop_sim(void)
{
	if (sim > 0) {
		int st = proc_stop(sim, SIGTERM, 5000);
		sim = -1;
		TEST_ASSERT_TRUE_MESSAGE(WIFEXITED(st) && WEXITSTATUS(st) == 0,
					 "cosim did not exit cleanly on SIGTERM");
	}
}

/* Wait for a frame on id; assert its length and bytes. */
static void expect(uint32_t id, const uint8_t *bytes, int len)
{
	uint8_t got[8] = { 0 };
	char msg[64];
	int n = can_wait_id(can_fd, id, got, WAIT_MS);

	snprintf(msg, sizeof msg, "no frame on 0x%03X within %d ms", id, WAIT_MS);
	TEST_ASSERT_TRUE_MESSAGE(n >= 0, msg);
	snprintf(msg, sizeof msg, "frame 0x%03X: length", id);
	TEST_ASSERT_EQUAL_INT_MESSAGE(len, n, msg);
	snprintf(msg, sizeof msg, "frame 0x%03X: bytes", id);
	TEST_ASSERT_EQUAL_HEX8_ARRAY_MESSAGE(bytes, got, (unsigned)len, msg);
}

/* Nothing on id for ms milliseconds. */
static void expect_none(uint32_t id, int ms)
{
	char msg[64];

	snprintf(msg, sizeof msg, "unexpected frame on 0x%03X", id);
	TEST_ASSERT_EQUAL_INT_MESSAGE(-ETIMEDOUT, can_wait_id(can_fd, id, NULL, ms), msg);
}

static void send8(uint32_t id, const uint8_t *b)
{
	TEST_ASSERT_EQUAL_INT(0, can_send_std(can_fd, id, b, 8));
}

/* A request/answer pair: drain, send, expect the answer. */
static void transact(uint32_t req_id, const uint8_t *req, uint32_t resp_id, const uint8_t *resp)
{
	drain();
	send8(req_id, req);
	expect(resp_id, resp, 8);
}

static void wait_bootup(uint8_t node)
{
	static const uint8_t boot[1] = { 0x00 };
	expect(0x700u + node, boot, 1);
}

/* One control command; returns the reply (must start with "ok"). */
static void control(const char *cmd, char *reply, size_t len)
{
	struct sockaddr_un to = { .sun_family = AF_UNIX }, me = { .sun_family = AF_UNIX };
	int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
	char buf[1024];
	ssize_t n;

	TEST_ASSERT_TRUE(fd >= 0);
	/* autobind: an abstract address, so that cosim can answer */
	TEST_ASSERT_EQUAL_INT(0, bind(fd, (struct sockaddr *)&me, sizeof(sa_family_t)));
	snprintf(to.sun_path, sizeof to.sun_path, "%s", ctl);
	TEST_ASSERT_EQUAL_INT((int)strlen(cmd), (int)sendto(fd, cmd, strlen(cmd), 0,
							    (struct sockaddr *)&to, sizeof to));
	struct pollfd p = { .fd = fd, .events = POLLIN };
	TEST_ASSERT_EQUAL_INT_MESSAGE(1, poll(&p, 1, WAIT_MS), "no answer on the control socket");
	n = recv(fd, buf, sizeof buf - 1, 0);
	close(fd);
	TEST_ASSERT_TRUE(n > 0);
	buf[n] = 0;
	if (reply)
		snprintf(reply, len, "%s", buf);
	TEST_ASSERT_EQUAL_STRING_LEN_MESSAGE("ok", buf, 2, buf);
}

/* ---- fixture ------------------------------------------------------------------- */

void setUp(void)
{
	can_fd = can_open_raw("vcan0");
	if (can_fd < 0)
		TEST_IGNORE_MESSAGE("vcan0 missing: run under tests/vcan/run -n 3");
	snprintf(dir, sizeof dir, "/tmp/cosim-test.XXXXXX");
	TEST_ASSERT_NOT_NULL(mkdtemp(dir));
	snprintf(nv, sizeof nv, "%s/nv", dir);
	snprintf(ctl, sizeof ctl, "%s/ctl", dir);
	snprintf(log_path, sizeof log_path, "%s/cosim.log", dir);
	TEST_ASSERT_EQUAL_INT(0, mkdir(nv, 0755));
	start_sim(NULL);
	wait_bootup(1);
}

void tearDown(void)
{
	if (sim > 0) {
		proc_stop(sim, SIGTERM, 5000);
		sim = -1;
	}
	if (Unity.CurrentTestFailed && log_path[0])
		proc_dump_log(log_path, 40);
	if (can_fd >= 0)
		close(can_fd);
	can_fd = -1;
	if (dir[0]) {
		char cmd[128];
		snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
		if (system(cmd) != 0)
			fprintf(stderr, "cannot remove %s\n", dir);
		dir[0] = 0;
	}
}

/* ---- §3.1: SDO golden frames ------------------------------------------------------ */

static const uint8_t NMT_START_1[2] = { 0x01, 0x01 };

void test_identity_uploads(void)
{
	/* derived extras: 1000h, 1018h:1, 1017h = 1000 */
	transact(0x601, (const uint8_t[8]){ 0x40, 0x00, 0x10, 0x00 }, 0x581,
		 (const uint8_t[8]){ 0x43, 0x00, 0x10, 0x00, 0x94, 0x01, 0x04, 0x00 });
	transact(0x601, (const uint8_t[8]){ 0x40, 0x18, 0x10, 0x01 }, 0x581,
		 (const uint8_t[8]){ 0x43, 0x18, 0x10, 0x01, 0x50, 0x02, 0x00, 0x00 });
	transact(0x601, (const uint8_t[8]){ 0x40, 0x18, 0x10, 0x04 }, 0x581,
		 (const uint8_t[8]){ 0x43, 0x18, 0x10, 0x04, 0x40, 0xE2, 0x01, 0x00 });
	transact(0x601, (const uint8_t[8]){ 0x40, 0x17, 0x10, 0x00 }, 0x581,
		 (const uint8_t[8]){ 0x4B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0x00, 0x00 });
	/* 2005h:1 span 100.0 */
	transact(0x601, (const uint8_t[8]){ 0x40, 0x05, 0x20, 0x01 }, 0x581,
		 (const uint8_t[8]){ 0x43, 0x05, 0x20, 0x01, 0x00, 0x00, 0xC8, 0x42 });
	/* 1A00h = {1, 0x20030020} */
	transact(0x601, (const uint8_t[8]){ 0x40, 0x00, 0x1A, 0x01 }, 0x581,
		 (const uint8_t[8]){ 0x43, 0x00, 0x1A, 0x01, 0x20, 0x00, 0x03, 0x20 });
	/* abort for 2001h: object does not exist */
	transact(0x601, (const uint8_t[8]){ 0x40, 0x01, 0x20, 0x00 }, 0x581,
		 (const uint8_t[8]){ 0x80, 0x01, 0x20, 0x00, 0x00, 0x00, 0x02, 0x06 });
}

void test_segmented_upload_of_device_name(void)
{
	/* 1008h "STI-SIM" is 7 bytes: segmented, size indicated */
	transact(0x601, (const uint8_t[8]){ 0x40, 0x08, 0x10, 0x00 }, 0x581,
		 (const uint8_t[8]){ 0x41, 0x08, 0x10, 0x00, 0x07, 0x00, 0x00, 0x00 });
	/* one segment, toggle 0, 0 bytes unused, last */
	transact(0x601, (const uint8_t[8]){ 0x60 }, 0x581,
		 (const uint8_t[8]){ 0x01, 'S', 'T', 'I', '-', 'S', 'I', 'M' });
}

void test_golden_v1_to_v8(void)
{
	/* V1/V2 */
	transact(0x601, (const uint8_t[8]){ 0x2B, 0x17, 0x10, 0x00, 0xA0, 0x0F, 0x00, 0x00 }, 0x581,
		 (const uint8_t[8]){ 0x60, 0x17, 0x10, 0x00 });
	/* V3/V4 (corrected: 23h for 4 bytes) */
	transact(0x601, (const uint8_t[8]){ 0x23, 0x04, 0x20, 0x01, 0xA4, 0x70, 0x9D, 0x3F }, 0x581,
		 (const uint8_t[8]){ 0x60, 0x04, 0x20, 0x01 });
	/* V5/V6 (corrected: 43h) */
	transact(0x601, (const uint8_t[8]){ 0x40, 0x04, 0x20, 0x01 }, 0x581,
		 (const uint8_t[8]){ 0x43, 0x04, 0x20, 0x01, 0xA4, 0x70, 0x9D, 0x3F });
	/* V7/V8 (corrected: "save" = 73 61 76 65) */
	transact(0x601, (const uint8_t[8]){ 0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65 }, 0x581,
		 (const uint8_t[8]){ 0x60, 0x10, 0x10, 0x01 });
	/* the printed (wrong) forms, strict device: 2Bh with 4 bytes (length
	 * too low) and the reversed signature are refused */
	transact(0x601, (const uint8_t[8]){ 0x2B, 0x04, 0x20, 0x01, 0xA4, 0x70, 0x9D, 0x3F }, 0x581,
		 (const uint8_t[8]){ 0x80, 0x04, 0x20, 0x01, 0x13, 0x00, 0x07, 0x06 });
	transact(0x601, (const uint8_t[8]){ 0x23, 0x10, 0x10, 0x01, 0x65, 0x76, 0x61, 0x73 }, 0x581,
		 (const uint8_t[8]){ 0x80, 0x10, 0x10, 0x01, 0x20, 0x00, 0x00, 0x08 });
	/* lenient: both printed forms accepted */
	control("sdo lenient on", NULL, 0);
	transact(0x601, (const uint8_t[8]){ 0x2B, 0x04, 0x20, 0x01, 0xA4, 0x70, 0x9D, 0x3F }, 0x581,
		 (const uint8_t[8]){ 0x60, 0x04, 0x20, 0x01 });
	transact(0x601, (const uint8_t[8]){ 0x2B, 0x10, 0x10, 0x01, 0x65, 0x76, 0x61, 0x73 }, 0x581,
		 (const uint8_t[8]){ 0x60, 0x10, 0x10, 0x01 });
}

void test_tpdo_v9_real32(void)
{
	control("pressure 6.25", NULL, 0);
	drain();
	TEST_ASSERT_EQUAL_INT(0, can_send_std(can_fd, 0x000, NMT_START_1, 2));
	expect(0x701, (const uint8_t[1]){ 0x05 }, 1); /* HB: operational */
	/* V9: 181#0000C840 = 6.25f, DLC 4 (event timer 1 s) */
	expect(0x181, (const uint8_t[4]){ 0x00, 0x00, 0xC8, 0x40 }, 4);
	/* the zero offset enters the process value: (6.25 + 1.75) * 100 / 100 */
	transact(0x601, (const uint8_t[8]){ 0x23, 0x04, 0x20, 0x01, 0x00, 0x00, 0xE0, 0x3F }, 0x581,
		 (const uint8_t[8]){ 0x60, 0x04, 0x20, 0x01 });
	sleep_ms(300);
	drain();
	expect(0x181, (const uint8_t[4]){ 0x00, 0x00, 0x00, 0x41 }, 4); /* 8.0f */
}

/* ---- store: "save" survives a power cycle ---------------------------------------- */

void test_save_survives_restart(void)
{
	/* 1017h = 2000 ms, save, restart with the same --nv */
	transact(0x601, (const uint8_t[8]){ 0x2B, 0x17, 0x10, 0x00, 0xD0, 0x07, 0x00, 0x00 }, 0x581,
		 (const uint8_t[8]){ 0x60, 0x17, 0x10, 0x00 });
	transact(0x601, (const uint8_t[8]){ 0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65 }, 0x581,
		 (const uint8_t[8]){ 0x60, 0x10, 0x10, 0x01 });
	/* changed after the save: must not survive */
	transact(0x601, (const uint8_t[8]){ 0x23, 0x04, 0x20, 0x01, 0xA4, 0x70, 0x9D, 0x3F }, 0x581,
		 (const uint8_t[8]){ 0x60, 0x04, 0x20, 0x01 });
	stop_sim();
	start_sim(NULL);
	wait_bootup(1);
	transact(0x601, (const uint8_t[8]){ 0x40, 0x17, 0x10, 0x00 }, 0x581,
		 (const uint8_t[8]){ 0x4B, 0x17, 0x10, 0x00, 0xD0, 0x07, 0x00, 0x00 });
	transact(0x601, (const uint8_t[8]){ 0x40, 0x04, 0x20, 0x01 }, 0x581,
		 (const uint8_t[8]){ 0x43, 0x04, 0x20, 0x01, 0x00, 0x00, 0x00, 0x00 });
	/* 1011h "load", restart: the device file's 1000 ms again */
	transact(0x601, (const uint8_t[8]){ 0x23, 0x11, 0x10, 0x01, 0x6C, 0x6F, 0x61, 0x64 }, 0x581,
		 (const uint8_t[8]){ 0x60, 0x11, 0x10, 0x01 });
	stop_sim();
	start_sim(NULL);
	wait_bootup(1);
	transact(0x601, (const uint8_t[8]){ 0x40, 0x17, 0x10, 0x00 }, 0x581,
		 (const uint8_t[8]){ 0x4B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0x00, 0x00 });
}

/* ---- §3.2: LSS ---------------------------------------------------------------------- */

void test_lss_golden_frames(void)
{
	/* L1: switch global -> configuration (no reply) */
	drain();
	send8(0x7E5, (const uint8_t[8]){ 0x04, 0x01 });
	expect_none(0x7E4, 300);
	/* L2/L3: inquire node-ID */
	transact(0x7E5, (const uint8_t[8]){ 0x5E }, 0x7E4, (const uint8_t[8]){ 0x5E, 0x01 });
	/* inquire identity ([std] 5Ah..5Dh) */
	transact(0x7E5, (const uint8_t[8]){ 0x5A }, 0x7E4,
		 (const uint8_t[8]){ 0x5A, 0x50, 0x02, 0x00, 0x00 });
	transact(0x7E5, (const uint8_t[8]){ 0x5D }, 0x7E4,
		 (const uint8_t[8]){ 0x5D, 0x40, 0xE2, 0x01, 0x00 });
	/* L6/L7: bit timing: index 4 (125k) ok, index 0 (1M) not supported */
	transact(0x7E5, (const uint8_t[8]){ 0x13, 0x00, 0x04 }, 0x7E4,
		 (const uint8_t[8]){ 0x13, 0x00, 0x00 });
	transact(0x7E5, (const uint8_t[8]){ 0x13, 0x00, 0x00 }, 0x7E4,
		 (const uint8_t[8]){ 0x13, 0x01, 0x00 });
	/* L4/L5: configure node-ID 5; 0 is refused (EC 1) */
	transact(0x7E5, (const uint8_t[8]){ 0x11, 0x00 }, 0x7E4, (const uint8_t[8]){ 0x11, 0x01 });
	transact(0x7E5, (const uint8_t[8]){ 0x11, 0x05 }, 0x7E4, (const uint8_t[8]){ 0x11, 0x00 });
	/* L8/L9: store */
	transact(0x7E5, (const uint8_t[8]){ 0x17 }, 0x7E4, (const uint8_t[8]){ 0x17, 0x00 });
	/* L10: back to waiting */
	drain();
	send8(0x7E5, (const uint8_t[8]){ 0x04, 0x00 });
	expect_none(0x7E4, 300);
	/* L11-L15: switch selective with a wrong serial: silence */
	drain();
	send8(0x7E5, (const uint8_t[8]){ 0x40, 0x50, 0x02 });
	send8(0x7E5, (const uint8_t[8]){ 0x41 });
	send8(0x7E5, (const uint8_t[8]){ 0x42 });
	send8(0x7E5, (const uint8_t[8]){ 0x43, 0x41, 0xE2, 0x01 });
	expect_none(0x7E4, 500);
	/* ... and with its own serial 123456: selected */
	drain();
	send8(0x7E5, (const uint8_t[8]){ 0x40, 0x50, 0x02 });
	send8(0x7E5, (const uint8_t[8]){ 0x41 });
	send8(0x7E5, (const uint8_t[8]){ 0x42 });
	send8(0x7E5, (const uint8_t[8]){ 0x43, 0x40, 0xE2, 0x01 });
	expect(0x7E4, (const uint8_t[8]){ 0x44 }, 8);
	send8(0x7E5, (const uint8_t[8]){ 0x04, 0x00 });
	/* reset communication (all nodes): the new node-ID takes effect,
	 * with its predefined SDO COB-IDs */
	drain();
	TEST_ASSERT_EQUAL_INT(0, can_send_std(can_fd, 0x000, (const uint8_t[2]){ 0x82, 0x00 }, 2));
	wait_bootup(5);
	transact(0x605, (const uint8_t[8]){ 0x40, 0x00, 0x10, 0x00 }, 0x585,
		 (const uint8_t[8]){ 0x43, 0x00, 0x10, 0x00, 0x94, 0x01, 0x04, 0x00 });
	transact(0x605, (const uint8_t[8]){ 0x40, 0x14, 0x10, 0x00 }, 0x585,
		 (const uint8_t[8]){ 0x43, 0x14, 0x10, 0x00, 0x85, 0x00, 0x00, 0x00 });
	/* the stored node-ID survives a restart */
	stop_sim();
	start_sim(NULL);
	wait_bootup(5);
}

/* ---- faults ----------------------------------------------------------------------- */

static const uint8_t UP_1000[8] = { 0x40, 0x00, 0x10, 0x00 };
static const uint8_t ANS_1000[8] = { 0x43, 0x00, 0x10, 0x00, 0x94, 0x01, 0x04, 0x00 };

void test_fault_sdo_silent(void)
{
	control("sdo silent on", NULL, 0);
	drain();
	send8(0x601, UP_1000);
	expect_none(0x581, 1500);
	control("sdo silent off", NULL, 0);
	sleep_ms(1200); /* the server's own 1 s timeout ends the silent transfer */
	transact(0x601, UP_1000, 0x581, ANS_1000);
}

void test_fault_sdo_abort(void)
{
	control("sdo abort 0x06060000", NULL, 0);
	transact(0x601, UP_1000, 0x581,
		 (const uint8_t[8]){ 0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x06, 0x06 });
	/* restricted to one object: others answer normally */
	control("sdo abort 0x08000022 0x2004:01", NULL, 0);
	transact(0x601, UP_1000, 0x581, ANS_1000);
	transact(0x601, (const uint8_t[8]){ 0x40, 0x04, 0x20, 0x01 }, 0x581,
		 (const uint8_t[8]){ 0x80, 0x04, 0x20, 0x01, 0x22, 0x00, 0x00, 0x08 });
	control("sdo abort off", NULL, 0);
	transact(0x601, UP_1000, 0x581, ANS_1000);
}

void test_fault_sdo_delay(void)
{
	control("sdo delay 800", NULL, 0);
	drain();
	uint64_t t0 = mono_ms();
	send8(0x601, UP_1000);
	expect(0x581, ANS_1000, 8);
	uint64_t dt = mono_ms() - t0;
	TEST_ASSERT_TRUE_MESSAGE(dt >= 750, "SDO answer came too early");
	control("sdo delay 0", NULL, 0);
}

void test_fault_pdo_badlen(void)
{
	uint8_t d[8];

	control("pdo badlen on", NULL, 0);
	drain();
	TEST_ASSERT_EQUAL_INT(0, can_send_std(can_fd, 0x000, NMT_START_1, 2));
	int n = can_wait_id(can_fd, 0x181, d, WAIT_MS);
	TEST_ASSERT_TRUE_MESSAGE(n >= 0, "no TPDO");
	TEST_ASSERT_NOT_EQUAL_INT(4, n);
	control("pdo badlen off", NULL, 0);
	drain();
	TEST_ASSERT_EQUAL_INT(4, can_wait_id(can_fd, 0x181, d, WAIT_MS));
}

void test_fault_heartbeat_stop(void)
{
	char reply[256];

	expect(0x701, (const uint8_t[1]){ 0x7F }, 1); /* pre-operational, 1 s */
	control("hb stop", NULL, 0);
	drain();
	expect_none(0x701, 2000);
	/* the rest of the device still answers */
	transact(0x601, UP_1000, 0x581, ANS_1000);
	control("hb start", NULL, 0);
	expect(0x701, (const uint8_t[1]){ 0x7F }, 1);
	control("status", reply, sizeof reply);
	TEST_ASSERT_NOT_NULL(strstr(reply, "pre-operational"));
}

void test_fault_silent_and_emcy(void)
{
	/* EMCY 5000h: register bit 0 set */
	drain();
	control("emcy 0x5000", NULL, 0);
	expect(0x081, (const uint8_t[8]){ 0x00, 0x50, 0x01 }, 8);
	control("emcy clear", NULL, 0);
	expect(0x081, (const uint8_t[8]){ 0 }, 8);
	/* cable pulled: no heartbeat, no SDO answer */
	control("silent on", NULL, 0);
	drain();
	send8(0x601, UP_1000);
	expect_none(0x581, 1200);
	expect_none(0x701, 1200);
	control("silent off", NULL, 0);
	expect(0x701, (const uint8_t[1]){ 0x7F }, 1);
	transact(0x601, UP_1000, 0x581, ANS_1000);
}

/* Several nodes in one process: two transducers told apart by their serial
 * and an I/O module whose outputs loop back to its inputs. */
void test_three_nodes_in_one_process(void)
{
	stop_sim();
	const char *argv[] = { COSIM,        "-i",        "vcan0",
			       "--nv",       nv,          "--control",
			       ctl,          "-d",        DEVICE,
			       "-d",         DEVICE ":3", "--serial",
			       "654321",     "-d",        "etc/devices/io-generic.json",
			       "--loopback", NULL };
	drain();
	sim = proc_spawn(argv, log_path, NULL);
	TEST_ASSERT_TRUE(sim > 0);
	wait_bootup(1); /* boot-ups in start order */
	wait_bootup(3);
	wait_bootup(2);
	/* switch selective for 654321: only node 3 answers */
	drain();
	send8(0x7E5, (const uint8_t[8]){ 0x40, 0x50, 0x02 });
	send8(0x7E5, (const uint8_t[8]){ 0x41 });
	send8(0x7E5, (const uint8_t[8]){ 0x42 });
	send8(0x7E5, (const uint8_t[8]){ 0x43, 0xF1, 0xFB, 0x09 });
	expect(0x7E4, (const uint8_t[8]){ 0x44 }, 8);
	expect_none(0x7E4, 500);
	transact(0x7E5, (const uint8_t[8]){ 0x5E }, 0x7E4, (const uint8_t[8]){ 0x5E, 0x03 });
	send8(0x7E5, (const uint8_t[8]){ 0x04, 0x00 });
	/* commands address one node */
	control("node 3 pressure 6.25", NULL, 0);
	/* start all; RPDO 1 of the I/O module (202h) comes back on TPDO 1 */
	drain();
	TEST_ASSERT_EQUAL_INT(0, can_send_std(can_fd, 0x000, (const uint8_t[2]){ 0x01, 0x00 }, 2));
	expect(0x183, (const uint8_t[4]){ 0x00, 0x00, 0xC8, 0x40 }, 4);
	sleep_ms(200);
	drain();
	TEST_ASSERT_EQUAL_INT(0, can_send_std(can_fd, 0x202, (const uint8_t[2]){ 0x03, 0xA5 }, 2));
	expect(0x182, (const uint8_t[2]){ 0x03, 0xA5 }, 2);
	transact(0x602, (const uint8_t[8]){ 0x40, 0x00, 0x60, 0x02 }, 0x582,
		 (const uint8_t[8]){ 0x4F, 0x00, 0x60, 0x02, 0xA5 });
}

void test_bad_device_file_is_refused(void)
{
	char path[128], badlog[128];
	FILE *f;
	int st;

	snprintf(path, sizeof path, "%s/bad.json", dir);
	snprintf(badlog, sizeof badlog, "%s/bad.log", dir);
	f = fopen(path, "w");
	TEST_ASSERT_NOT_NULL(f);
	fputs("{\"node_id\": 1, \"tpdos\": [{\"map\": [\"0x2003:00:32\"]}]}\n", f);
	fclose(f);
	const char *argv[] = { COSIM, "-i", "vcan0", "-d", path, NULL };
	pid_t p = proc_spawn(argv, badlog, NULL);
	TEST_ASSERT_TRUE(p > 0);
	uint64_t until = mono_ms() + WAIT_MS;
	while (!proc_exited(p, &st) && mono_ms() < until)
		sleep_ms(20);
	TEST_ASSERT_TRUE(WIFEXITED(st));
	TEST_ASSERT_EQUAL_INT(3, WEXITSTATUS(st));
	TEST_ASSERT_TRUE(file_contains(
		badlog, "bad.json: tpdos[0].map[0]: object 0x2003:00 does not exist"));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_identity_uploads);
	RUN_TEST(test_segmented_upload_of_device_name);
	RUN_TEST(test_golden_v1_to_v8);
	RUN_TEST(test_tpdo_v9_real32);
	RUN_TEST(test_save_survives_restart);
	RUN_TEST(test_lss_golden_frames);
	RUN_TEST(test_fault_sdo_silent);
	RUN_TEST(test_fault_sdo_abort);
	RUN_TEST(test_fault_sdo_delay);
	RUN_TEST(test_fault_pdo_badlen);
	RUN_TEST(test_fault_heartbeat_stop);
	RUN_TEST(test_fault_silent_and_emcy);
	RUN_TEST(test_three_nodes_in_one_process);
	RUN_TEST(test_bad_device_file_is_refused);
	return UNITY_END();
}
