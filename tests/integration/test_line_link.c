/* SPDX-License-Identifier: MIT */
/*
 * An interface that goes and comes back under the running daemon
 * (docs/troubleshooting.md "An interface that goes and comes back"), on
 * vcan in the VM, with a client reading in a loop on each line:
 *   - `ip link set vcan0 down` / `up`, three times: the line reports it
 *     (link-down episode), refuses bus requests with MBX_E_STATE while
 *     down, resumes by itself; its clients stay; the manager's node is
 *     supervised and booted again; line 1 sees no failed call;
 *   - `ip link del vcan0` / `ip link add vcan0`, three times: the same,
 *     with a new socket on the new interface (its receive filter too);
 *     the device is switched on again with it and booted by the manager;
 *   - the same under load: besides the two readers, RPDOs injected on
 *     vcan0 every 10 ms are forwarded (B000h, docs/gateway.md) to line 1's
 *     event-driven TPDO on vcan1; after each return the forwarding
 *     resumes by itself, and line 1's reader never fails.
 * Prints the failed calls and the time from the interface's return to the
 * first answered SDO read (and the first forwarded PDO). Line 1's SDO
 * time-out is long (1.5 s): a call there must not fail for a scheduling
 * delay of the emulated VM, only for what line 0 went through.
 * Run: tests/vcan/run -n 2 -- build/san/tests/integration/test_line_link
 */
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "core/frame.h"
#include "core/manager.h"
#include "mailbox/cogw.h"
#include "mailbox/cogw_health.h"
#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"
#include "unity.h"

#define INSTANCE "linkt"
#define NODE0 5
#define NODE1 3
#define ROUNDS 3
/* Line 0's RPDO 1 (181h) writes B000h, line 1's TPDO 1 (1FFh, event-driven)
 * maps it: PDO forwarding from the line whose interface goes away. */
#define RPDO_IN 0x181
#define TPDO_OUT 0x1FF
#define CONFIG                                                                                 \
	"{\"version\": 1, \"mailbox\": {\"instance\": \"" INSTANCE "\"},"                      \
	" \"gateway\": {\"process_image\": [{\"index\": \"0xB000\", \"type\": \"UNSIGNED32\"," \
	"  \"access\": \"rw\", \"pdo\": true}]}, \"lines\": ["                                 \
	"{\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127, "                  \
	" \"sdo_timeout_ms\": 300, \"rpdos\": 1, "                                             \
	" \"manager\": {\"retry_ms\": 300, \"reset_wait_ms\": 1000}, "                         \
	" \"nodes\": [{\"id\": 5, \"heartbeat_ms\": 1000}],"                                   \
	" \"values\": [{\"index\": \"0x1400\", \"sub\": 1, \"value\": \"0x181\"},"             \
	"  {\"index\": \"0x1600\", \"sub\": 1, \"value\": \"0xB0000020\"},"                    \
	"  {\"index\": \"0x1600\", \"sub\": 0, \"value\": 1}]},"                               \
	"{\"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": 127, "                  \
	" \"sdo_timeout_ms\": 1500, \"tpdos\": 1,"                                             \
	" \"values\": [{\"index\": \"0x1800\", \"sub\": 1, \"value\": \"0x1FF\"},"             \
	"  {\"index\": \"0x1A00\", \"sub\": 1, \"value\": \"0xB0000020\"},"                    \
	"  {\"index\": \"0x1A00\", \"sub\": 0, \"value\": 1}]}]}"

static daemon_run dmn;
static cosim_run sim0, sim1;
static cogw *h;

/* A client reading 1018h:1 of one node in a loop, on its own handle. */
typedef struct reader {
	unsigned line;
	uint8_t node;
	pthread_t thread;
	atomic_bool stop;
	atomic_uint ok, refused, failed;
	atomic_int last_rc;
	atomic_uint last_abort;
} reader;

static reader r0 = { .line = 0, .node = NODE0 }, r1 = { .line = 1, .node = NODE1 };

static void *read_loop(void *arg)
{
	reader *r = arg;
	cogw *own = NULL;
	if (cogw_open(&own, INSTANCE) != 0)
		return NULL;
	while (!atomic_load(&r->stop)) {
		uint32_t v = 0, abort = 0;
		int rc = cogw_sdo_read_u32(own, r->line, r->node, 0x1018, 1, &v, 2000, &abort);
		if (rc == 0)
			atomic_fetch_add(&r->ok, 1);
		else if (rc == COGW_E_STATE)
			atomic_fetch_add(&r->refused, 1);
		else {
			atomic_fetch_add(&r->failed, 1);
			atomic_store(&r->last_rc, rc);
			atomic_store(&r->last_abort, abort);
		}
		sleep_ms(20);
	}
	cogw_close(own);
	return NULL;
}

static bool readers_running;

static void readers_start(void)
{
	TEST_ASSERT_EQUAL_INT(0, pthread_create(&r0.thread, NULL, read_loop, &r0));
	TEST_ASSERT_EQUAL_INT(0, pthread_create(&r1.thread, NULL, read_loop, &r1));
	readers_running = true;
}

static void readers_stop(void)
{
	if (!readers_running)
		return;
	readers_running = false;
	atomic_store(&r0.stop, true);
	atomic_store(&r1.stop, true);
	pthread_join(r0.thread, NULL);
	pthread_join(r1.thread, NULL);
}

static void restore_vcan0(void)
{
	if (system("ip link add dev vcan0 type vcan 2>/dev/null; ip link set vcan0 up") != 0) {
		/* reported by the next test that needs it */
	}
}

void setUp(void)
{
	memset(&dmn, 0, sizeof dmn);
	memset(&sim0, 0, sizeof sim0);
	memset(&sim1, 0, sizeof sim1);
	h = NULL;
	for (reader *r = &r0; r; r = r == &r0 ? &r1 : NULL) {
		atomic_store(&r->stop, false);
		atomic_store(&r->ok, 0);
		atomic_store(&r->refused, 0);
		atomic_store(&r->failed, 0);
	}
}

void tearDown(void)
{
	readers_stop(); /* a failed test left them running */
	restore_vcan0();
	if (h)
		cogw_close(h);
	cosim_stop(&sim0, 3000);
	cosim_stop(&sim1, 3000);
	daemon_cleanup(&dmn);
	daemon_unlink_queues(INSTANCE);
}

static bool bit(const mbx_mgr_bits *b, unsigned n)
{
	return (b->w[n / 32] >> (n % 32)) & 1u;
}

static int wait_node_booted(int timeout_ms)
{
	mbx_mgr_status st;
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	for (;;) {
		if (cogw_mgr_status(h, 0, &st, 3000) == 0 && st.state == CO_MGR_OPERATIONAL &&
		    bit(&st.booted, NODE0))
			return 0;
		if (mono_ms() > until)
			return -1;
		sleep_ms(100);
	}
}

static int wait_link(bool down, int timeout_ms)
{
	mbx_line_health hl;
	uint64_t until = mono_ms() + (uint64_t)timeout_ms;
	for (;;) {
		if (cogw_line_health(h, 0, &hl, 3000) == 0 &&
		    hl.fault[MBX_FAULT_LINK_DOWN].active == down)
			return 0;
		if (mono_ms() > until)
			return -1;
		sleep_ms(20);
	}
}

/* ms from now until an SDO read on line 0 is answered (-1: not in 10 s) */
static long until_answered(void)
{
	uint64_t t0 = mono_ms();
	while (mono_ms() - t0 < 10000) {
		uint32_t v, abort;
		if (cogw_sdo_read_u32(h, 0, NODE0, 0x1018, 1, &v, 500, &abort) == 0)
			return (long)(mono_ms() - t0);
		sleep_ms(10);
	}
	return -1;
}

static void start(void)
{
	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = CONFIG,
								    .instance = INSTANCE,
								    .n_lines = 2 }));
	TEST_ASSERT_EQUAL_INT(0, cogw_open(&h, INSTANCE));
	const char *dev0[] = { "etc/devices/io-generic.json:5", NULL };
	const char *dev1[] = { "etc/devices/io-generic.json:3", NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim0, dmn.dir, 0, dev0, NULL));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim1, dmn.dir, 1, dev1, NULL));
	TEST_ASSERT_EQUAL_INT(0, wait_node_booted(20000));
}

/* What both tests check at the end: line 1 untouched, line 0 back. */
static void finish(const char *what, long worst_ms)
{
	mbx_line_health hl;
	TEST_ASSERT_EQUAL_INT(0, wait_node_booted(15000));
	sleep_ms(300);
	readers_stop();
	printf("%s x%d: line 0 reader %u ok, %u refused (link down), %u failed; line 1 reader %u "
	       "ok, %u refused, %u failed; slowest first answer after the return %ld ms\n",
	       what, ROUNDS, atomic_load(&r0.ok), atomic_load(&r0.refused), atomic_load(&r0.failed),
	       atomic_load(&r1.ok), atomic_load(&r1.refused), atomic_load(&r1.failed), worst_ms);
	if (atomic_load(&r1.failed))
		printf("line 1 reader: last failure %s, abort %08X\n",
		       cogw_strerror(atomic_load(&r1.last_rc)), atomic_load(&r1.last_abort));
	TEST_ASSERT_EQUAL_UINT(0, atomic_load(&r1.failed));
	TEST_ASSERT_EQUAL_UINT(0, atomic_load(&r1.refused));
	TEST_ASSERT_TRUE(atomic_load(&r1.ok) > 0);
	TEST_ASSERT_TRUE(atomic_load(&r0.refused) > 0);
	TEST_ASSERT_EQUAL_INT(0, cogw_line_health(h, 0, &hl, 3000));
	TEST_ASSERT_EQUAL_UINT32(ROUNDS, hl.fault[MBX_FAULT_LINK_DOWN].episodes);
	TEST_ASSERT_EQUAL_INT(0, cogw_line_health(h, 1, &hl, 3000));
	TEST_ASSERT_EQUAL_UINT32(0, hl.fault[MBX_FAULT_LINK_DOWN].episodes);
}

static void test_link_down_and_up_repeatedly(void)
{
	long worst = 0;
	start();
	readers_start();
	for (int round = 1; round <= ROUNDS; round++) {
		sleep_ms(500);
		TEST_ASSERT_EQUAL_INT(0, system("ip link set vcan0 down"));
		TEST_ASSERT_EQUAL_INT(0, wait_link(true, 3000));
		uint32_t v, abort;
		TEST_ASSERT_EQUAL_INT(COGW_E_STATE,
				      cogw_sdo_read_u32(h, 0, NODE0, 0x1018, 1, &v, 2000, &abort));
		/* what does not need the bus still works */
		mbx_line_status st;
		TEST_ASSERT_EQUAL_INT(0, cogw_line_status(h, 0, &st, 3000));
		sleep_ms(700);
		TEST_ASSERT_EQUAL_INT(0, system("ip link set vcan0 up"));
		long ms = until_answered();
		TEST_ASSERT_TRUE_MESSAGE(ms >= 0, "no SDO answer after the interface came back");
		TEST_ASSERT_EQUAL_INT(0, wait_link(false, 3000));
		if (ms > worst)
			worst = ms;
	}
	finish("link down/up", worst);
}

static void test_interface_deleted_and_created_again(void)
{
	long worst = 0;
	start();
	readers_start();
	for (int round = 1; round <= ROUNDS; round++) {
		sleep_ms(500);
		TEST_ASSERT_EQUAL_INT(0, system("ip link del vcan0"));
		TEST_ASSERT_EQUAL_INT(0, wait_link(true, 3000));
		/* the device's bus is gone with it: switched on again below */
		cosim_stop(&sim0, 3000);
		uint32_t v, abort;
		TEST_ASSERT_EQUAL_INT(COGW_E_STATE,
				      cogw_sdo_read_u32(h, 0, NODE0, 0x1018, 1, &v, 2000, &abort));
		sleep_ms(700);
		TEST_ASSERT_EQUAL_INT(
			0, system("ip link add dev vcan0 type vcan && ip link set vcan0 up"));
		uint64_t back = mono_ms();
		TEST_ASSERT_EQUAL_INT(0, wait_link(false, 3000));
		const char *dev0[] = { "etc/devices/io-generic.json:5", NULL };
		TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim0, dmn.dir, 0, dev0, NULL));
		TEST_ASSERT_TRUE_MESSAGE(until_answered() >= 0,
					 "no SDO answer on the new interface");
		long ms = (long)(mono_ms() - back); /* with the device's own start */
		if (ms > worst)
			worst = ms;
		mbx_line_health hl;
		TEST_ASSERT_EQUAL_INT(0, cogw_line_health(h, 0, &hl, 3000));
		TEST_ASSERT_EQUAL_UINT32((uint32_t)round, hl.reopens);
	}
	finish("interface deleted/created", worst);
}

/* RPDOs on vcan0 every 10 ms, as a device would send them: a counter.
 * The socket goes with the interface; a new one is opened on the new
 * interface (tried every 10 ms). */
typedef struct injector {
	pthread_t thread;
	atomic_bool stop;
	atomic_uint sent, refused;
} injector;

static injector inj;

static void *inject_loop(void *arg)
{
	injector *in = arg;
	int fd = -1;
	uint32_t n = 0;
	while (!atomic_load(&in->stop)) {
		uint8_t b[4];
		if (fd < 0)
			fd = can_open_raw("vcan0");
		co_put_le32(b, ++n);
		if (fd >= 0 && can_send_std(fd, RPDO_IN, b, 4) == 0) {
			atomic_fetch_add(&in->sent, 1);
		} else {
			atomic_fetch_add(&in->refused, 1);
			if (fd >= 0)
				close(fd);
			fd = -1;
		}
		sleep_ms(10);
	}
	if (fd >= 0)
		close(fd);
	return NULL;
}

/* ms from `since` to the first forwarded TPDO on fd1 (-1: none in 10 s). */
static long until_forwarded(int fd1, uint64_t since)
{
	uint8_t d[8];
	if (can_wait_id(fd1, TPDO_OUT, d, 10000) < 0)
		return -1;
	return (long)(mono_ms() - since);
}

/* Forget the frames received so far (those forwarded before the outage). */
static void drain_fd(int fd)
{
	uint8_t f[16];
	while (recv(fd, f, sizeof f, MSG_DONTWAIT) > 0)
		;
}

static void test_deleted_under_load_with_forwarded_pdos(void)
{
	long worst_sdo = 0, worst_pdo = 0;
	int fd1 = can_open_raw("vcan1");
	TEST_ASSERT_TRUE(fd1 >= 0);
	start();
	uint8_t start_cmd[2] = { 0x01, 127 }; /* line 1's node: PDOs need OPERATIONAL */
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd1, 0x000, start_cmd, 2));
	readers_start();
	atomic_store(&inj.stop, false);
	TEST_ASSERT_EQUAL_INT(0, pthread_create(&inj.thread, NULL, inject_loop, &inj));
	TEST_ASSERT_TRUE_MESSAGE(until_forwarded(fd1, mono_ms()) >= 0, "no forwarded PDO");
	for (int round = 1; round <= ROUNDS; round++) {
		sleep_ms(500);
		TEST_ASSERT_EQUAL_INT(0, system("ip link del vcan0"));
		TEST_ASSERT_EQUAL_INT(0, wait_link(true, 3000));
		cosim_stop(&sim0, 3000);
		sleep_ms(700);
		drain_fd(fd1);
		/* from the command on: the injector may send on the new interface
		 * before system() returns */
		uint64_t back = mono_ms();
		TEST_ASSERT_EQUAL_INT(
			0, system("ip link add dev vcan0 type vcan && ip link set vcan0 up"));
		long pdo = until_forwarded(fd1, back);
		TEST_ASSERT_TRUE_MESSAGE(pdo >= 0, "PDO forwarding did not resume");
		const char *dev0[] = { "etc/devices/io-generic.json:5", NULL };
		TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim0, dmn.dir, 0, dev0, NULL));
		TEST_ASSERT_TRUE_MESSAGE(until_answered() >= 0,
					 "no SDO answer on the new interface");
		long sdo = (long)(mono_ms() - back);
		printf("round %d: first forwarded PDO %ld ms, first answered SDO %ld ms after "
		       "`ip link add` (with the device's start)\n",
		       round, pdo, sdo);
		worst_pdo = pdo > worst_pdo ? pdo : worst_pdo;
		worst_sdo = sdo > worst_sdo ? sdo : worst_sdo;
	}
	atomic_store(&inj.stop, true);
	pthread_join(inj.thread, NULL);
	close(fd1);
	printf("under load: %u RPDOs injected, %u not sent (interface gone); slowest first "
	       "forwarded PDO after the return %ld ms\n",
	       atomic_load(&inj.sent), atomic_load(&inj.refused), worst_pdo);
	finish("interface deleted/created under load", worst_sdo);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_link_down_and_up_repeatedly);
	RUN_TEST(test_interface_deleted_and_created_again);
	RUN_TEST(test_deleted_under_load_with_forwarded_pdos);
	return UNITY_END();
}
