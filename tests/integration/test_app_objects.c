/* SPDX-License-Identifier: MIT */
/*
 * tests/integration/test_app_objects.c - objects a client owns on the
 * daemon's own node (docs/application.md), with the real cogwd on vcan0,
 * an owner (a libcogw handle answering indications on a thread of this
 * process, whose behaviour each case sets), other mailbox clients and an
 * SDO client on the bus (a raw socket, tests/integration/support/sdo_req.h):
 *
 *  - served objects read and written from the bus in every mode (expedited,
 *    segmented, block; a DOMAIN streamed in place) and from the mailbox
 *    (OD_READ/OD_WRITE, SDO to the own node) and through cogw-ascii (CiA
 *    309-3): the owner's values;
 *  - a refused write: the owner's abort code on the bus, nothing applied;
 *    a read answer that does not fit: 06040047h, the owner told (PARAM);
 *  - a silent owner: 08000020h when the SDO timeout runs out, its late
 *    answer refused; an owner gone or released: 08000021h;
 *  - held objects: bus reads never ask the owner, the owner's value in the
 *    TPDO that maps it, writes by others and RPDO values told to it;
 *  - hostile input: 1000h..1FFFh, another client's object, beyond the
 *    bounds, answers to indications never given, too many indications
 *    open (060A0023h) while the line keeps serving everyone else.
 *
 * Run from the repository root:
 *   make build/san/tests/integration/test_app_objects build/san/bin/cogwd
 *   tests/vcan/run -n 3 -- tests/run-tests integration \
 *        build/san/tests/integration/test_app_objects
 * COGW_TEST_ONLY=<part of a test name> runs only the matching tests.
 */
#include <errno.h>
#include <pthread.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/sdo.h"
#include "mailbox/cogw.h"
#include "tests/integration/support/daemon.h"
#include "tests/integration/support/proc.h"
#include "tests/integration/support/sdo_req.h"
#include "unity.h"

#define INSTANCE "itapp"
#define OWN_NODE 100 /* the daemon's node-ID on vcan0 */
#define TOOL_NODE 5  /* the SDO client on the bus */
#define SERVED_U32 0x2100
#define SERVED_DOMAIN 0x2101
#define HELD_U16 0x2102  /* mapped into the daemon's TPDO 1 (18Ah... see config) */
#define HELD_RPDO 0x2103 /* written by the daemon's RPDO 1 (COB-ID 205h) */
#define DOMAIN_CAP 4096u
#define TPDO_COB 0x1E4
#define RPDO_COB 0x205
#define SDO_TIMEOUT_MS 1000

static daemon_run dmn;
static int can_fd = -1;
static sdo_req tool;

/* ---- the owner: a thread answering its indications -------------------------------- */

enum owner_mode {
	OWNER_ANSWER, /* reads: the stored value; writes: accept and store */
	OWNER_REFUSE, /* refuse with owner_abort */
	OWNER_SILENT, /* never answer (kept: late_ind) */
	OWNER_SHORT,  /* reads: a value 2 bytes short */
};

static struct owner {
	cogw *h;
	pthread_t thread;
	atomic_bool stop;
	atomic_int mode;
	uint32_t abort;
	/* the values it serves */
	pthread_mutex_t lock;
	uint32_t u32;
	uint8_t domain[DOMAIN_CAP];
	size_t domain_len;
	/* what it saw */
	atomic_uint reads, writes, written, cancels;
	atomic_uint last_written_origin;
	atomic_uint last_written_index;
	atomic_uint late_ind; /* the last indication left unanswered */
	atomic_int last_answer_rc;
} own;

static void owner_write(const mbx_ev_app_ind *ind, const uint8_t *data)
{
	uint8_t *buf = malloc(ind->size ? ind->size : 1);
	TEST_ASSERT_NOT_NULL(buf);
	size_t len = ind->inline_len;
	memcpy(buf, data, len);
	if (ind->inline_len < ind->size)
		TEST_ASSERT_EQUAL(0,
				  cogw_app_ind_data(own.h, 0, ind->ind, buf, ind->size, &len, 0));
	pthread_mutex_lock(&own.lock);
	if (ind->index == SERVED_U32 && len == 4)
		memcpy(&own.u32, buf, 4);
	else if (ind->index == SERVED_DOMAIN && len <= DOMAIN_CAP) {
		memcpy(own.domain, buf, len);
		own.domain_len = len;
	}
	pthread_mutex_unlock(&own.lock);
	free(buf);
	cogw_app_answer(own.h, 0, ind->ind, 0, NULL, 0, 0);
}

static void owner_indication(const cogw_msg *m)
{
	mbx_ev_app_ind ind;
	const uint8_t *data;
	if (cogw_app_ind_parse(m->data, m->len, &ind, &data) < 0)
		return;
	if (ind.op == MBX_APP_OP_READ)
		atomic_fetch_add(&own.reads, 1);
	else
		atomic_fetch_add(&own.writes, 1);
	int mode = atomic_load(&own.mode);
	if (mode == OWNER_SILENT) {
		atomic_store(&own.late_ind, ind.ind);
		return;
	}
	if (mode == OWNER_REFUSE) {
		cogw_app_answer(own.h, 0, ind.ind, own.abort, NULL, 0, 0);
		return;
	}
	if (ind.op == MBX_APP_OP_WRITE)
		return owner_write(&ind, data);
	uint8_t buf[DOMAIN_CAP];
	size_t len = mode == OWNER_SHORT ? 2 : 4;
	pthread_mutex_lock(&own.lock);
	if (ind.index == SERVED_U32)
		memcpy(buf, &own.u32, 4);
	else {
		len = own.domain_len;
		memcpy(buf, own.domain, len);
	}
	pthread_mutex_unlock(&own.lock);
	atomic_store(&own.last_answer_rc, cogw_app_answer(own.h, 0, ind.ind, 0, buf, len, 0));
}

static void *owner_main(void *arg)
{
	(void)arg;
	while (!atomic_load(&own.stop)) {
		cogw_msg m;
		if (cogw_recv(own.h, &m, 50) < 0)
			continue;
		if (m.kind == MBX_KIND_EVENT && m.code == MBX_EV_APP_IND) {
			owner_indication(&m);
		} else if (m.kind == MBX_KIND_EVENT && m.code == MBX_EV_APP_WRITTEN) {
			mbx_ev_app_written w;
			const uint8_t *d;
			if (cogw_app_written_parse(m.data, m.len, &w, &d) == 0) {
				atomic_store(&own.last_written_origin, w.origin);
				atomic_store(&own.last_written_index, w.index);
				atomic_fetch_add(&own.written, 1);
			}
		} else if (m.kind == MBX_KIND_EVENT && m.code == MBX_EV_APP_CANCEL) {
			atomic_fetch_add(&own.cancels, 1);
		}
		cogw_msg_release(&m);
	}
	return NULL;
}

static const mbx_app_claim_req claim_served_u32 = { .index = SERVED_U32, .kind = MBX_APP_SERVED };
static const mbx_app_claim_req claim_served_domain = { .index = SERVED_DOMAIN,
						       .kind = MBX_APP_SERVED };
static const mbx_app_claim_req claim_held_u16 = { .index = HELD_U16, .kind = MBX_APP_HELD };
static const mbx_app_claim_req claim_held_rpdo = { .index = HELD_RPDO, .kind = MBX_APP_HELD };

static void owner_start(void)
{
	memset(&own, 0, sizeof own);
	pthread_mutex_init(&own.lock, NULL);
	own.u32 = 0x11223344;
	TEST_ASSERT_EQUAL(0, cogw_open(&own.h, INSTANCE));
	TEST_ASSERT_EQUAL(0, cogw_app_claim(own.h, 0, &claim_served_u32, NULL, 0, 0));
	TEST_ASSERT_EQUAL(0, cogw_app_claim(own.h, 0, &claim_served_domain, NULL, 0, 0));
	TEST_ASSERT_EQUAL(0, cogw_app_claim(own.h, 0, &claim_held_u16, NULL, 0, 0));
	TEST_ASSERT_EQUAL(0, cogw_app_claim(own.h, 0, &claim_held_rpdo, NULL, 0, 0));
	TEST_ASSERT_EQUAL(0, pthread_create(&own.thread, NULL, owner_main, NULL));
}

static void owner_stop(void)
{
	if (!own.h)
		return;
	atomic_store(&own.stop, true);
	pthread_join(own.thread, NULL);
	cogw_close(own.h);
	own.h = NULL;
	pthread_mutex_destroy(&own.lock);
}

/* ---- the bus side ---------------------------------------------------------------------- */

static uint32_t bus_read(uint16_t index, uint8_t mode, uint8_t *buf, uint32_t cap, uint32_t *len)
{
	sdo_client_req r = { .upload = true,
			     .node_id = OWN_NODE,
			     .index = index,
			     .mode = mode,
			     .buf = buf,
			     .cap = cap };
	TEST_ASSERT_EQUAL(
		0, sdo_req_transfer(&tool, &r, 30000)); /* 430 confirmed segments under emulation */
	if (len)
		*len = tool.res.size;
	return tool.res.abort;
}

static uint32_t bus_write(uint16_t index, uint8_t mode, const uint8_t *data, uint32_t size)
{
	sdo_client_req r = {
		.node_id = OWN_NODE, .index = index, .mode = mode, .data = data, .size = size
	};
	TEST_ASSERT_EQUAL(
		0, sdo_req_transfer(&tool, &r, 30000)); /* 430 confirmed segments under emulation */
	return tool.res.abort;
}

static void fill_pattern(uint8_t *buf, size_t len, unsigned seed)
{
	for (size_t i = 0; i < len; i++)
		buf[i] = (uint8_t)(seed * 131u + i * 7u + (i >> 8) * 13u + 1u);
}

/* ---- fixture --------------------------------------------------------------------------- */

static char config_json[4096];

static void write_config(void)
{
	snprintf(config_json, sizeof config_json,
		 "{\"version\": 1,\n"
		 " \"mailbox\": {\"instance\": \"" INSTANCE "\", \"max_clients\": 16},\n"
		 " \"lines\": [{\"name\": \"line0\", \"interface\": \"vcan0\", \"bitrate\": "
		 "1000000, \"node_id\": %d,\n"
		 "   \"sdo_timeout_ms\": %d, \"heartbeat_ms\": 0, \"rpdos\": 1, \"tpdos\": 1,\n"
		 "   \"objects\": [\n"
		 "    {\"index\": \"0x2100\", \"type\": \"UNSIGNED32\", \"access\": \"rw\"},\n"
		 "    {\"index\": \"0x2101\", \"type\": \"DOMAIN\", \"access\": \"rw\", "
		 "\"max_size\": %u},\n"
		 "    {\"index\": \"0x2102\", \"type\": \"UNSIGNED16\", \"access\": \"rwr\", "
		 "\"pdo\": true, \"default\": 7},\n"
		 "    {\"index\": \"0x2103\", \"type\": \"UNSIGNED16\", \"access\": \"rww\", "
		 "\"pdo\": true}],\n"
		 "   \"values\": [\n"
		 "    {\"index\": \"0x1800\", \"sub\": 1, \"value\": \"0x%X\"},\n"
		 "    {\"index\": \"0x1800\", \"sub\": 2, \"value\": 254},\n"
		 "    {\"index\": \"0x1A00\", \"sub\": 0, \"value\": 1},\n"
		 "    {\"index\": \"0x1A00\", \"sub\": 1, \"value\": \"0x21020010\"},\n"
		 "    {\"index\": \"0x1400\", \"sub\": 1, \"value\": \"0x%X\"},\n"
		 "    {\"index\": \"0x1400\", \"sub\": 2, \"value\": 254},\n"
		 "    {\"index\": \"0x1600\", \"sub\": 0, \"value\": 1},\n"
		 "    {\"index\": \"0x1600\", \"sub\": 1, \"value\": \"0x21030010\"}],\n"
		 "   \"app\": {\"max_created\": 3, \"max_per_client\": 8, \"indications\": 2,\n"
		 "     \"objects\": [\n"
		 "      {\"index\": \"0x2100\", \"kind\": \"served\", \"uid\": %u},\n"
		 "      {\"index\": \"0x2101\", \"kind\": \"served\", \"uid\": %u},\n"
		 "      {\"index\": \"0x2102\", \"kind\": \"held\", \"uid\": %u},\n"
		 "      {\"index\": \"0x2103\", \"kind\": \"held\", \"uid\": %u}]}}]}\n",
		 OWN_NODE, SDO_TIMEOUT_MS, DOMAIN_CAP, TPDO_COB, RPDO_COB, getuid(), getuid(),
		 getuid(), getuid());
}

void setUp(void)
{
	write_config();
	daemon_opts o = { .config_json = config_json, .instance = INSTANCE, .n_lines = 1 };
	TEST_ASSERT_EQUAL(0, daemon_start(&dmn, &o));
	can_fd = can_open_raw("vcan0");
	TEST_ASSERT_TRUE(can_fd >= 0);
	TEST_ASSERT_EQUAL(0, sdo_req_init(&tool, can_fd, TOOL_NODE, 2000));
	owner_start();
}

void tearDown(void)
{
	owner_stop();
	sdo_req_fini(&tool);
	if (can_fd >= 0)
		close(can_fd);
	can_fd = -1;
	daemon_cleanup(&dmn);
}

/* ---- served objects ---------------------------------------------------------------- */

static void test_served_u32_from_the_bus_in_every_mode(void)
{
	static const uint8_t modes[] = { SDO_MODE_EXPEDITED, SDO_MODE_SEGMENTED, SDO_MODE_BLOCK };
	for (unsigned i = 0; i < sizeof modes; i++) {
		uint8_t v[4];
		uint32_t len = 0;
		uint32_t w = 0xA0B0C0D0u + i;
		TEST_ASSERT_EQUAL_HEX32(0, bus_write(SERVED_U32, modes[i], (uint8_t *)&w, 4));
		TEST_ASSERT_EQUAL_HEX32(w, own.u32); /* the owner has it */
		TEST_ASSERT_EQUAL_HEX32(0, bus_read(SERVED_U32, modes[i], v, sizeof v, &len));
		TEST_ASSERT_EQUAL(4, len);
		TEST_ASSERT_EQUAL_MEMORY(&w, v, 4);
	}
	TEST_ASSERT_EQUAL(3, atomic_load(&own.reads));
	TEST_ASSERT_EQUAL(3, atomic_load(&own.writes));
}

static void test_served_domain_segmented_and_block(void)
{
	static uint8_t data[3000], back[DOMAIN_CAP];
	static const uint8_t modes[] = { SDO_MODE_SEGMENTED, SDO_MODE_BLOCK };
	for (unsigned i = 0; i < sizeof modes; i++) {
		uint32_t len = 0;
		fill_pattern(data, sizeof data, i + 1);
		/* 4096 bytes of capacity: streamed in place, checked at the end */
		TEST_ASSERT_EQUAL_HEX32(0, bus_write(SERVED_DOMAIN, modes[i], data, sizeof data));
		TEST_ASSERT_EQUAL(sizeof data, own.domain_len);
		TEST_ASSERT_EQUAL_MEMORY(data, own.domain, sizeof data);
		TEST_ASSERT_EQUAL_HEX32(0,
					bus_read(SERVED_DOMAIN, modes[i], back, sizeof back, &len));
		TEST_ASSERT_EQUAL(sizeof data, len);
		TEST_ASSERT_EQUAL_MEMORY(data, back, sizeof data);
	}
}

static void test_served_from_the_mailbox(void)
{
	cogw *c;
	uint32_t v = 0, abort = 0;
	size_t len = 0;
	TEST_ASSERT_EQUAL(0, cogw_open(&c, INSTANCE));
	TEST_ASSERT_EQUAL(0, cogw_od_read(c, 0, SERVED_U32, 0, &v, sizeof v, &len, 0, &abort));
	TEST_ASSERT_EQUAL_HEX32(0x11223344, v);
	v = 0x55667788;
	TEST_ASSERT_EQUAL(0, cogw_od_write(c, 0, SERVED_U32, 0, &v, 4, 0, &abort));
	TEST_ASSERT_EQUAL_HEX32(0x55667788, own.u32);
	/* an SDO request to the daemon's own node-ID: the same path */
	v = 0;
	TEST_ASSERT_EQUAL(0, cogw_sdo_read_u32(c, 0, OWN_NODE, SERVED_U32, 0, &v, 0, &abort));
	TEST_ASSERT_EQUAL_HEX32(0x55667788, v);
	/* a DOMAIN larger than one message, both ways (chunked) */
	static uint8_t big[DOMAIN_CAP], back[DOMAIN_CAP];
	fill_pattern(big, sizeof big, 9);
	TEST_ASSERT_EQUAL(0, cogw_od_write(c, 0, SERVED_DOMAIN, 0, big, sizeof big, 0, &abort));
	TEST_ASSERT_EQUAL_MEMORY(big, own.domain, sizeof big);
	TEST_ASSERT_EQUAL(0,
			  cogw_od_read(c, 0, SERVED_DOMAIN, 0, back, sizeof back, &len, 0, &abort));
	TEST_ASSERT_EQUAL(sizeof big, len);
	TEST_ASSERT_EQUAL_MEMORY(big, back, sizeof big);
	/* the owner keeps a served value: asking itself would wait for itself */
	TEST_ASSERT_EQUAL(COGW_E_STATE,
			  cogw_od_read(own.h, 0, SERVED_U32, 0, &v, sizeof v, &len, 0, &abort));
	cogw_close(c);
}

/* The CiA 309-3 gateway reaches a served object as any other object of
 * the daemon's node: the owner's value, the owner's refusal. */
static void ascii_ask(int fd, const char *cmd, char *answer, size_t cap)
{
	size_t len = 0;
	TEST_ASSERT_EQUAL((ssize_t)strlen(cmd), send(fd, cmd, strlen(cmd), MSG_NOSIGNAL));
	while (!memchr(answer, '\n', len) && len < cap - 1) {
		ssize_t k = recv(fd, answer + len, cap - 1 - len, 0);
		TEST_ASSERT_TRUE(k > 0);
		len += (size_t)k;
	}
	answer[len] = '\0';
}

static void test_served_through_cogw_ascii(void)
{
	char path[DAEMON_PATH_MAX + 16], log[DAEMON_PATH_MAX + 16], answer[128];
	snprintf(path, sizeof path, "%s/ascii.sock", dmn.dir);
	snprintf(log, sizeof log, "%s/ascii.log", dmn.dir);
	const char *argv[] = { "build/san/bin/cogw-ascii",
			       "--daemon-config",
			       dmn.config_path,
			       "--socket",
			       path,
			       NULL };
	pid_t gw = proc_spawn(argv, log, NULL);
	TEST_ASSERT_TRUE(gw > 0);
	bool up = file_wait_contains(log, "serving instance", 10000);
	struct sockaddr_un a = { .sun_family = AF_UNIX };
	TEST_ASSERT_TRUE(strlen(path) < sizeof a.sun_path);
	memcpy(a.sun_path, path, strlen(path) + 1);
	int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
	bool ok = up && fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) == 0;
	if (ok) {
		ascii_ask(fd, "1 100 r 0x2100 0 u32\n", answer, sizeof answer);
		ok = !strcmp(answer, "287454020\r\n"); /* 11223344h */
	}
	if (ok) {
		atomic_store(&own.mode, OWNER_REFUSE);
		own.abort = SDO_AB_VALUE_HIGH;
		ascii_ask(fd, "1 100 w 0x2100 0 u32 5\n", answer, sizeof answer);
		ok = !strcmp(answer, "ERROR: 0x06090031\r\n");
	}
	if (fd >= 0)
		close(fd);
	proc_stop(gw, SIGTERM, 5000);
	if (!ok)
		proc_dump_log(log, 20);
	TEST_ASSERT_TRUE_MESSAGE(up, "cogw-ascii did not start");
	TEST_ASSERT_EQUAL_STRING("ERROR: 0x06090031\r\n", answer);
	TEST_ASSERT_EQUAL(1, atomic_load(&own.reads));
	TEST_ASSERT_EQUAL(1, atomic_load(&own.writes));
}

static void test_refused_write_is_the_owners_abort_and_applies_nothing(void)
{
	uint32_t w = 0xDEAD, v = 0;
	cogw *c;
	uint32_t abort = 0;
	atomic_store(&own.mode, OWNER_REFUSE);
	own.abort = SDO_AB_VALUE_HIGH; /* 06090031h */
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_HIGH,
				bus_write(SERVED_U32, SDO_MODE_EXPEDITED, (uint8_t *)&w, 4));
	TEST_ASSERT_EQUAL(0, cogw_open(&c, INSTANCE));
	TEST_ASSERT_EQUAL(COGW_E_ABORT, cogw_od_write(c, 0, SERVED_U32, 0, &w, 4, 0, &abort));
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE_HIGH, abort);
	atomic_store(&own.mode, OWNER_ANSWER);
	TEST_ASSERT_EQUAL_HEX32(0,
				bus_read(SERVED_U32, SDO_MODE_EXPEDITED, (uint8_t *)&v, 4, NULL));
	TEST_ASSERT_EQUAL_HEX32(0x11223344, v);
	cogw_close(c);
}

static void test_owner_value_that_does_not_fit(void)
{
	uint8_t v[4];
	atomic_store(&own.mode, OWNER_SHORT);
	TEST_ASSERT_EQUAL_HEX32(0x06040047, bus_read(SERVED_U32, SDO_MODE_EXPEDITED, v, 4, NULL));
	for (int i = 0; i < 100 && !atomic_load(&own.last_answer_rc); i++)
		sleep_ms(10);
	TEST_ASSERT_EQUAL(COGW_E_PARAM, atomic_load(&own.last_answer_rc));
	/* the next read is served again */
	atomic_store(&own.mode, OWNER_ANSWER);
	TEST_ASSERT_EQUAL_HEX32(0, bus_read(SERVED_U32, SDO_MODE_SEGMENTED, v, 4, NULL));
	TEST_ASSERT_EQUAL_HEX32(0x11223344, *(uint32_t *)v);
}

static void test_silent_owner_gets_late_abort_and_its_late_answer_is_refused(void)
{
	uint8_t v[4];
	atomic_store(&own.mode, OWNER_SILENT);
	TEST_ASSERT_EQUAL_HEX32(0x08000020, bus_read(SERVED_U32, SDO_MODE_EXPEDITED, v, 4, NULL));
	uint32_t late = atomic_load(&own.late_ind);
	TEST_ASSERT_NOT_EQUAL(0, late);
	for (int i = 0; i < 50 && !atomic_load(&own.cancels); i++)
		sleep_ms(10);
	TEST_ASSERT_EQUAL(1, atomic_load(&own.cancels)); /* told it ended */
	TEST_ASSERT_EQUAL(COGW_E_PARAM, cogw_app_answer(own.h, 0, late, 0, v, 4, 0));
	/* never given at all */
	TEST_ASSERT_EQUAL(COGW_E_PARAM, cogw_app_answer(own.h, 0, 0x7777, 0, v, 4, 0));
	mbx_app_status st;
	mbx_app_obj objs[8];
	size_t n = 0;
	TEST_ASSERT_EQUAL(0, cogw_app_list(own.h, 0, &st, objs, 8, &n, 0));
	TEST_ASSERT_EQUAL(1, st.ind_late);
	TEST_ASSERT_EQUAL(2, st.answers_refused);
	TEST_ASSERT_EQUAL(4, n);
}

static void test_owner_gone_or_released_answers_no_owner(void)
{
	uint8_t v[4];
	TEST_ASSERT_EQUAL(0, cogw_app_release(own.h, 0, SERVED_U32, 0, 0));
	TEST_ASSERT_EQUAL_HEX32(0x08000021, bus_read(SERVED_U32, SDO_MODE_EXPEDITED, v, 4, NULL));
	/* the owner leaves while an indication waits for it */
	atomic_store(&own.mode, OWNER_SILENT);
	sdo_client_req r = { .upload = true,
			     .node_id = OWN_NODE,
			     .index = SERVED_DOMAIN,
			     .mode = SDO_MODE_SEGMENTED,
			     .buf = v,
			     .cap = sizeof v };
	TEST_ASSERT_EQUAL(0, sdo_req_submit(&tool, &r));
	for (int i = 0; i < 100 && !atomic_load(&own.late_ind); i++)
		sdo_req_step(&tool, 10);
	TEST_ASSERT_NOT_EQUAL(0, atomic_load(&own.late_ind));
	owner_stop(); /* unregisters: the daemon ends its indications */
	for (int i = 0; i < 300 && !tool.done; i++)
		sdo_req_step(&tool, 10);
	TEST_ASSERT_TRUE(tool.done);
	TEST_ASSERT_EQUAL_HEX32(0x08000021, tool.res.abort);
	/* another client of the same user may claim the objects now */
	cogw *c;
	TEST_ASSERT_EQUAL(0, cogw_open(&c, INSTANCE));
	TEST_ASSERT_EQUAL(0, cogw_app_claim(c, 0, &claim_served_domain, NULL, 0, 0));
	cogw_close(c);
}

/* ---- held objects ------------------------------------------------------------------ */

static void test_held_value_in_sdo_and_tpdo_and_writes_told(void)
{
	uint16_t v = 0;
	uint8_t d[8];
	unsigned reads = atomic_load(&own.reads);
	TEST_ASSERT_EQUAL_HEX32(0, bus_read(HELD_U16, SDO_MODE_EXPEDITED, (uint8_t *)&v, 2, NULL));
	TEST_ASSERT_EQUAL(7, v); /* the default, without asking the owner */
	TEST_ASSERT_EQUAL(reads, atomic_load(&own.reads));
	/* operational, so that PDOs run */
	uint8_t start[2] = { 0x01, OWN_NODE };
	TEST_ASSERT_EQUAL(0, can_send_std(can_fd, 0x000, start, 2));
	sleep_ms(100);
	uint16_t w = 0x4321;
	TEST_ASSERT_EQUAL(0, cogw_pdo_write(own.h, 0, HELD_U16, 0, &w, 2, 1, 0));
	TEST_ASSERT_EQUAL(2, can_wait_id(can_fd, TPDO_COB, d, 2000));
	TEST_ASSERT_EQUAL_HEX8(0x21, d[0]);
	TEST_ASSERT_EQUAL_HEX8(0x43, d[1]);
	TEST_ASSERT_EQUAL(0, atomic_load(&own.written)); /* its own write */
	/* a write from the bus: applied, and the owner hears of it */
	w = 0x0102;
	TEST_ASSERT_EQUAL_HEX32(0, bus_write(HELD_U16, SDO_MODE_EXPEDITED, (uint8_t *)&w, 2));
	for (int i = 0; i < 100 && !atomic_load(&own.written); i++)
		sleep_ms(10);
	TEST_ASSERT_EQUAL(1, atomic_load(&own.written));
	TEST_ASSERT_EQUAL(MBX_APP_FROM_SDO, atomic_load(&own.last_written_origin));
	/* an RPDO's value */
	uint8_t rp[2] = { 0x34, 0x12 };
	TEST_ASSERT_EQUAL(0, can_send_std(can_fd, RPDO_COB, rp, 2));
	for (int i = 0; i < 100 && atomic_load(&own.written) < 2; i++)
		sleep_ms(10);
	TEST_ASSERT_EQUAL(2, atomic_load(&own.written));
	TEST_ASSERT_EQUAL(MBX_APP_FROM_RPDO, atomic_load(&own.last_written_origin));
	TEST_ASSERT_EQUAL_HEX16(HELD_RPDO, atomic_load(&own.last_written_index));
}

/* ---- hostile input -------------------------------------------------------------------- */

static void test_claims_out_of_range_foreign_and_beyond_the_bounds(void)
{
	cogw *c;
	TEST_ASSERT_EQUAL(0, cogw_open(&c, INSTANCE));
	mbx_app_claim_req r = { .index = 0x1017,
				.kind = MBX_APP_HELD,
				.type = MBX_T_UNSIGNED16,
				.access = MBX_APP_READ };
	TEST_ASSERT_EQUAL(COGW_E_PARAM, cogw_app_claim(c, 0, &r, NULL, 0, 0));
	r.index = 0xA000; /* beyond 9FFFh */
	TEST_ASSERT_EQUAL(COGW_E_PARAM, cogw_app_claim(c, 0, &r, NULL, 0, 0));
	/* another client's objects */
	TEST_ASSERT_EQUAL(COGW_E_ACCESS, cogw_app_claim(c, 0, &claim_served_u32, NULL, 0, 0));
	/* served objects map into no PDO */
	r = (mbx_app_claim_req){ .index = 0x3000,
				 .kind = MBX_APP_SERVED,
				 .type = MBX_T_UNSIGNED8,
				 .access = MBX_APP_READ | MBX_APP_TPDO };
	TEST_ASSERT_EQUAL(COGW_E_PARAM, cogw_app_claim(c, 0, &r, NULL, 0, 0));
	/* the line's bound of 3 created objects */
	r.access = MBX_APP_READ | MBX_APP_WRITE;
	for (uint8_t s = 0; s < 3; s++) {
		r.index = (uint16_t)(0x3000 + s);
		TEST_ASSERT_EQUAL(0, cogw_app_claim(c, 0, &r, NULL, 0, 0));
	}
	r.index = 0x3003;
	TEST_ASSERT_EQUAL(COGW_E_FULL, cogw_app_claim(c, 0, &r, NULL, 0, 0));
	/* a created object of another client: not claimable while owned */
	r.index = 0x3000;
	TEST_ASSERT_EQUAL(COGW_E_ACCESS, cogw_app_claim(own.h, 0, &r, NULL, 0, 0));
	/* its client gone, the same user claims it back, as created */
	cogw_close(c);
	TEST_ASSERT_EQUAL(0, cogw_open(&c, INSTANCE));
	TEST_ASSERT_EQUAL(0, cogw_app_claim(c, 0, &r, NULL, 0, 0));
	r.type = MBX_T_UNSIGNED16; /* not as created */
	r.index = 0x3001;
	TEST_ASSERT_EQUAL(COGW_E_PARAM, cogw_app_claim(c, 0, &r, NULL, 0, 0));
	cogw_close(c);
}

static void test_too_many_open_indications_and_the_line_keeps_serving(void)
{
	cogw *c;
	uint64_t corr[3];
	TEST_ASSERT_EQUAL(0, cogw_open(&c, INSTANCE));
	atomic_store(&own.mode, OWNER_SILENT);
	mbx_obj_req o = { .index = SERVED_U32 };
	/* the owner may have 2 open: the third read is refused at once */
	for (int i = 0; i < 3; i++)
		TEST_ASSERT_EQUAL(0,
				  cogw_send_async(c, 0, MBX_CMD_OD_READ, &o, sizeof o, &corr[i]));
	cogw_msg m;
	TEST_ASSERT_EQUAL(0, cogw_recv(c, &m, 2000));
	TEST_ASSERT_EQUAL(corr[2], m.corr);
	TEST_ASSERT_EQUAL(COGW_E_ABORT, m.status);
	TEST_ASSERT_EQUAL_HEX32(0x060A0023, m.abort);
	cogw_msg_release(&m);
	/* the line serves everyone else meanwhile: the client's own next
	 * request and a bus read of another object come back while the owner
	 * still holds two indications */
	uint32_t v = 0;
	size_t len = 0;
	uint32_t abort = 0;
	TEST_ASSERT_EQUAL(0, cogw_od_read(c, 0, HELD_U16, 0, &v, 2, &len, 0, &abort));
	TEST_ASSERT_EQUAL(0, bus_read(0x1000, SDO_MODE_EXPEDITED, (uint8_t *)&v, 4, NULL));
	mbx_app_status st;
	mbx_app_obj objs[8];
	size_t n = 0;
	TEST_ASSERT_EQUAL(0, cogw_app_list(c, 0, &st, objs, 8, &n, 0));
	TEST_ASSERT_EQUAL(1, st.ind_refused_full);
	/* the two open ones end with the deadline */
	for (int i = 0; i < 2; i++) {
		TEST_ASSERT_EQUAL(0, cogw_recv(c, &m, 2000));
		TEST_ASSERT_EQUAL(COGW_E_ABORT, m.status);
		TEST_ASSERT_EQUAL_HEX32(0x08000020, m.abort);
		cogw_msg_release(&m);
	}
	cogw_close(c);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_served_u32_from_the_bus_in_every_mode);
	RUN_TEST(test_served_domain_segmented_and_block);
	RUN_TEST(test_served_from_the_mailbox);
	RUN_TEST(test_served_through_cogw_ascii);
	RUN_TEST(test_refused_write_is_the_owners_abort_and_applies_nothing);
	RUN_TEST(test_owner_value_that_does_not_fit);
	RUN_TEST(test_silent_owner_gets_late_abort_and_its_late_answer_is_refused);
	RUN_TEST(test_owner_gone_or_released_answers_no_owner);
	RUN_TEST(test_held_value_in_sdo_and_tpdo_and_writes_told);
	RUN_TEST(test_claims_out_of_range_foreign_and_beyond_the_bounds);
	RUN_TEST(test_too_many_open_indications_and_the_line_keeps_serving);
	return UNITY_END();
}
