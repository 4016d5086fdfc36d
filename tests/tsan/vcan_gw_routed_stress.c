/* SPDX-License-Identifier: MIT */
/*
 * Routed mailbox SDO transfers under ThreadSanitizer (build/tsan), on real
 * line threads over vcan (run in the VM with the integration tests): the
 * real lines/ (line_sdo.c owns every transfer), gateway/ (the routing step
 * gw_mbx_hop.c, the relay leases gw_relay.c, the rings) and mailbox/.
 *
 * Three gateway lines (networks 1, 2, 3 on vcan0..2) and two devices (node
 * 5 on vcan1 and on vcan2, each a plain line whose SDO server serves a
 * 2000-byte domain). Client threads, each with handles of its own, ask any
 * gateway line for the domain of node 5 of network 2 or 3 (so: relayed
 * through another line, or on the line's own bus), segmented or block, and
 * then either wait for the answer or vanish: close the handle while the
 * transfer runs, at a random moment (before the lease opened, while it
 * relays, after the device answered). Meanwhile a requester on vcan0 sends
 * network indications to line 0's SDO server (routed sessions toward node
 * 5 of network 2) and ends each confirmed one at once or after the
 * device's first answer. So the lending board of lines 1 and 2 (gateway/
 * lend.h) is reserved and given back many times at once by three lines,
 * while those lines' own clients take from the same pools (a read asked of
 * the line the network is attached to).
 * Checked:
 * - no data race (TSan fails the run on one): the origin line and the
 *   target line share nothing but the rings;
 * - every answer that came is byte-exact, or a refusal the concurrency
 *   explains (0A000003: the device's server is in a transfer another line
 *   runs; a timeout when the emulated machine stalls);
 * - at the end no line holds a lease, and a transfer through every line
 *   to every network succeeds: nothing was left behind by the vanished;
 *   and every client channel of lines 1 and 2 can be lent again (four
 *   transfers to silent nodes at once each way end "no answer", none "no
 *   free client"): no reservation leaked.
 * A second run adds a requester of its own on vcan0 (a raw socket, the SDO
 * client side by hand): network indications to gateway line 0 for node 5
 * of network 2, then expedited and segmented reads, while the mailbox
 * clients run as above. Line 0 sends the requests on vcan1 itself and line
 * 1 the device's answers on vcan0 (docs/gateway.md, frames across
 * interfaces): each thread reads the other's state only through the rings
 * and the published done counts, which TSan checks; every answer must be
 * the device's, in order, and both directions must have gone across.
 */
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <sys/socket.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include "unity.h"

#include "core/co.h"
#include "core/od.h"
#include "core/sdo.h"
#include "gateway/convention.h"
#include "gateway/gateway.h"
#include "lines/line.h"
#include "mailbox/cogw.h"
#include "mailbox/proto.h"

#define GW_LINES 3u
#define DEVICES 2u
#define DEV_NODE 5u
#define DOMAIN_IDX 0x2100u
#define DOMAIN_LEN 2000u
#define VALUE_IDX 0x2000u /* an expedited UNSIGNED32 of the devices */
#define VALUE 0xC0FFEE05u
#define SHORT_IDX 0x2101u /* a short domain, read segmented by the requester */
#define SHORT_LEN 60u
#define REQ_ROUNDS 40u
#define CLIENTS 4u
#define ROUNDS 24u
#define SDO_TIMEOUT_MS 2000u

static const char *const ifname[] = { "vcan0", "vcan1", "vcan2" };

static gw *g;
static line *gw_line[GW_LINES], *dev_line[DEVICES];
static co_od *gw_od[GW_LINES], *dev_od[DEVICES];
static char gw_instance[32], dev_instance[32];
static uint8_t domain[DOMAIN_LEN];

/* Written by the client threads, judged by the main thread (Unity's
 * assertions belong to the thread that runs the test). */
static struct {
	atomic_uint answered, refused, no_client, timed_out, vanished;
	atomic_uint wrong_data, unexpected;
	atomic_uint last_unexpected; /* the abort or status it had */
	atomic_uint last_where;      /* its read: line * 100 + network * 10 + block */
	/* what "unexpected" holds besides aborts: a client that could not
	 * register, a request that could not be sent, an answer that never
	 * came (each with the last COGW_E_* it had) */
	atomic_uint open_failed, send_failed, no_answer;
	atomic_int last_open_rc, last_send_rc;
	/* the routed sessions of the requester on vcan0 */
	atomic_uint sess_confirmed, sess_busy, sess_no_client, sess_unexpected, sess_last;
} tally;

void setUp(void) {}

static void stop_all(void);

/* Also after a failed assertion: no line or queue outlives the test (the
 * next test in the VM would find the mqueue limit spent). */
void tearDown(void)
{
	stop_all();
}

static line *start_line(co_od *od, uint8_t index, const char *name, const char *ifn,
			const char *instance, uint8_t node_id, uint16_t net, const line_ext *x)
{
	static char qname[GW_LINES + DEVICES][MBX_QNAME_MAX];
	static unsigned nq;
	line *l = NULL;
	/* each run starts every line again: the names of the last run's
	 * (destroyed) lines are reused */
	char *q = qname[nq++ % (GW_LINES + DEVICES)];

	TEST_ASSERT_EQUAL(0, mbx_queue_name(q, MBX_QNAME_MAX, instance, index));
	line_params p = {
		.index = index,
		.name = name,
		.network_id = net,
		.can = { .ifname = ifn, .bitrate = 1000000 },
		.node = { .node_id = node_id,
			  .od = od,
			  .sdo_client_count = 4,
			  .sdo_client_timeout_ms = SDO_TIMEOUT_MS,
			  .sdo_server_timeout_ms = SDO_TIMEOUT_MS },
		.mbx = { .queue_name = q,
			 .unlink_existing = true,
			 .default_access = MBX_ACCESS_WRITE },
		.rt_cpu = -1,
		.main_wakefd = -1,
	};
	if (x)
		p.ext[0] = *x;
	TEST_ASSERT_EQUAL_INT(0, line_create(&l, &p));
	TEST_ASSERT_EQUAL_INT(0, line_start(l));
	for (int i = 0; i < 500 && !line_is_up(l); i++)
		usleep(10000);
	TEST_ASSERT_TRUE(line_is_up(l));
	return l;
}

static void start_all(void)
{
	gw_params gp = { .n_lines = GW_LINES };

	snprintf(gw_instance, sizeof gw_instance, "gwst%d", (int)getpid());
	snprintf(dev_instance, sizeof dev_instance, "gwdv%d", (int)getpid());
	for (unsigned i = 0; i < DOMAIN_LEN; i++)
		domain[i] = (uint8_t)(i * 7u + i / 251u);
	for (unsigned i = 0; i < GW_LINES; i++) {
		gp.line[i].network_id = (uint16_t)(i + 1);
		gp.line[i].sdo_timeout_ms = SDO_TIMEOUT_MS;
	}
	TEST_ASSERT_EQUAL_INT(0, gw_create(&g, &gp));
	for (unsigned i = 0; i < GW_LINES; i++) {
		char name[8];
		line_ext x;
		TEST_ASSERT_EQUAL(0, co_od_create(&gw_od[i], 16));
		/* 1F2Ch: network n is attached to line n - 1 */
		for (unsigned n = 1; n <= GW_LINES; n++)
			TEST_ASSERT_EQUAL(0, co_od_add_num(gw_od[i], GW_OBJ_ROUTES, (uint8_t)n,
							   CO_T_UNSIGNED32, CO_ACC_RW, n, NULL));
		snprintf(name, sizeof name, "gw%u", i);
		gw_line_ext(g, i, &x);
		gw_line[i] = start_line(gw_od[i], (uint8_t)i, name, ifname[i], gw_instance, 127,
					(uint16_t)(i + 1), &x);
	}
	for (unsigned d = 0; d < DEVICES; d++) {
		char name[8];
		TEST_ASSERT_EQUAL(0, co_od_create(&dev_od[d], 16));
		TEST_ASSERT_EQUAL(0,
				  co_od_add_bytes(dev_od[d], DOMAIN_IDX, 0, CO_T_DOMAIN, CO_ACC_RW,
						  DOMAIN_LEN, domain, DOMAIN_LEN, NULL));
		TEST_ASSERT_EQUAL(0,
				  co_od_add_bytes(dev_od[d], SHORT_IDX, 0, CO_T_DOMAIN, CO_ACC_RW,
						  SHORT_LEN, domain, SHORT_LEN, NULL));
		TEST_ASSERT_EQUAL(0, co_od_add_num(dev_od[d], VALUE_IDX, 0, CO_T_UNSIGNED32,
						   CO_ACC_RW, VALUE, NULL));
		snprintf(name, sizeof name, "dev%u", d);
		dev_line[d] = start_line(dev_od[d], (uint8_t)d, name, ifname[d + 1], dev_instance,
					 DEV_NODE, (uint16_t)(d + 2), NULL);
	}
}

static void stop_all(void)
{
	for (unsigned i = 0; i < GW_LINES; i++) {
		line_destroy(gw_line[i]);
		gw_line[i] = NULL;
	}
	for (unsigned d = 0; d < DEVICES; d++) {
		line_destroy(dev_line[d]);
		dev_line[d] = NULL;
	}
	gw_destroy(g);
	g = NULL;
	for (unsigned i = 0; i < GW_LINES; i++) {
		if (gw_od[i])
			co_od_destroy(gw_od[i]);
		gw_od[i] = NULL;
	}
	for (unsigned d = 0; d < DEVICES; d++) {
		if (dev_od[d])
			co_od_destroy(dev_od[d]);
		dev_od[d] = NULL;
	}
}

static cogw *open_client(void)
{
	cogw *h = NULL;
	cogw_options o = { .instance = gw_instance, .timeout_ms = 20000 };
	int rc = cogw_open_opts(&h, &o);

	if (rc) {
		atomic_fetch_add(&tally.open_failed, 1);
		atomic_store(&tally.last_open_rc, rc);
	}
	return rc == 0 ? h : NULL;
}

/* Ask line_no for the domain of node 5 of network net; 0 or COGW_E_*. */
static int start_read(cogw *h, unsigned line_no, uint16_t net, bool block, uint64_t *corr)
{
	mbx_gw_sdo_req r = { .net = net,
			     .sdo = { .node = DEV_NODE,
				      .index = DOMAIN_IDX,
				      .mode = block ? SDO_MODE_BLOCK : SDO_MODE_SEGMENTED,
				      .size = DOMAIN_LEN } };

	return cogw_send_async(h, line_no, MBX_CMD_GW_SDO_UPLOAD, &r, sizeof r, corr);
}

/* The answer to corr: 0, the abort it carried, or UINT32_MAX (no answer,
 * a status other than ABORT, or wrong data: counted). Any thread. */
static uint32_t take_answer(cogw *h, uint64_t corr)
{
	cogw_msg m;

	for (int i = 0; i < 100; i++) {
		if (cogw_recv(h, &m, 30000) != 0)
			break;
		if (m.kind != MBX_KIND_RESPONSE || m.corr != corr) {
			cogw_msg_release(&m);
			continue;
		}
		uint32_t abort = m.abort;
		if (!m.status && (m.len != DOMAIN_LEN || memcmp(domain, m.data, DOMAIN_LEN))) {
			atomic_fetch_add(&tally.wrong_data, 1);
			abort = UINT32_MAX;
		} else if (m.status && (m.status != COGW_E_ABORT || !abort)) {
			atomic_store(&tally.last_unexpected, (unsigned)m.status);
			abort = UINT32_MAX;
		}
		cogw_msg_release(&m);
		return abort;
	}
	atomic_fetch_add(&tally.no_answer, 1);
	return UINT32_MAX;
}

/* On the main thread: a read that must succeed. */
static void expect_success(cogw *h, unsigned line_no, uint16_t net, bool block)
{
	uint64_t corr = 0;
	TEST_ASSERT_EQUAL_INT(0, start_read(h, line_no, net, block, &corr));
	uint32_t abort = take_answer(h, corr);
	char why[48];

	snprintf(why, sizeof why, "abort or failure %08X", (unsigned)abort);
	TEST_ASSERT_EQUAL_HEX32_MESSAGE(0, abort, why);
}

/* What the concurrency explains: the device's server in a transfer
 * another line runs (0A000003), every SDO client of the target line lent
 * (060A0023), a stall of the emulated machine (a timeout). */
static void count(uint32_t abort, unsigned where)
{
	if (!abort)
		atomic_fetch_add(&tally.answered, 1);
	else if (abort == SDO_AB_ROUTE_BUSY)
		atomic_fetch_add(&tally.refused, 1);
	else if (abort == SDO_AB_NO_RESOURCE)
		atomic_fetch_add(&tally.no_client, 1);
	else if (abort == SDO_AB_TIMEOUT || abort == SDO_AB_NODE_UNKNOWN)
		atomic_fetch_add(&tally.timed_out, 1);
	else {
		atomic_fetch_add(&tally.unexpected, 1);
		atomic_store(&tally.last_where, where);
		if (abort != UINT32_MAX)
			atomic_store(&tally.last_unexpected, abort);
	}
}

static void *client(void *arg)
{
	unsigned seed = (unsigned)(uintptr_t)arg * 2654435761u;

	for (unsigned round = 0; round < ROUNDS; round++) {
		cogw *h = open_client();
		unsigned line_no = rand_r(&seed) % GW_LINES;
		uint16_t net = (uint16_t)(2 + rand_r(&seed) % 2);
		uint64_t corr = 0;
		bool block = rand_r(&seed) & 1;
		unsigned where = line_no * 100u + net * 10u + block;
		int rc = h ? start_read(h, line_no, net, block, &corr) : -1;

		if (rc) {
			if (h) {
				atomic_fetch_add(&tally.send_failed, 1);
				atomic_store(&tally.last_send_rc, rc);
			}
			count(UINT32_MAX, where);
			cogw_close(h);
			continue;
		}

		if (rand_r(&seed) % 2) {
			/* vanish: the transfer is anywhere from waiting in the
			 * pool to done */
			usleep(rand_r(&seed) % 40000);
			atomic_fetch_add(&tally.vanished, 1);
		} else {
			count(take_answer(h, corr), where);
		}
		cogw_close(h);
	}
	return NULL;
}

/* ---- a requester on vcan0: routed sessions through line 0's SDO server ---- */

static int raw_open(const char *ifn, uint32_t rx_id)
{
	struct sockaddr_can a = { .can_family = AF_CAN, .can_ifindex = (int)if_nametoindex(ifn) };
	struct can_filter f = { .can_id = rx_id, .can_mask = CAN_SFF_MASK };
	int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);

	if (fd < 0)
		return -1;
	if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, &f, sizeof f) ||
	    bind(fd, (struct sockaddr *)&a, sizeof a)) {
		close(fd);
		return -1;
	}
	return fd;
}

static void raw_send(int fd, uint32_t id, const uint8_t d[8])
{
	struct can_frame cf = { .can_id = id, .len = 8 };

	memcpy(cf.data, d, 8);
	if (write(fd, &cf, sizeof cf) != sizeof cf)
		atomic_fetch_add(&tally.sess_unexpected, 1);
}

/* The next frame within ms, or false. */
static bool raw_recv(int fd, uint8_t d[8], int ms)
{
	struct pollfd p = { .fd = fd, .events = POLLIN };
	struct can_frame cf;

	if (poll(&p, 1, ms) != 1 || read(fd, &cf, sizeof cf) != sizeof cf)
		return false;
	memcpy(d, cf.data, 8);
	return true;
}

/* Sessions begun and given up (an abort after the confirmation, or after
 * an upload's initiate), spread over the mailbox clients' rounds. */
static void *giving_up_requester(void *arg)
{
	unsigned seed = 77u;
	int fd = raw_open("vcan0", 0x580 + 127);
	static const uint8_t ind[8] = { 0xE0, 2, 0, DEV_NODE, 0, 0, 0, 0 };
	static const uint8_t up[8] = { 0x40, DOMAIN_IDX & 0xFF, DOMAIN_IDX >> 8, 0, 0, 0, 0, 0 };
	static const uint8_t ab[8] = { 0x80, DOMAIN_IDX & 0xFF, DOMAIN_IDX >> 8, 0, 0, 0, 0, 8 };
	uint8_t d[8];

	(void)arg;
	if (fd < 0) {
		atomic_fetch_add(&tally.sess_unexpected, 1);
		return NULL;
	}
	for (unsigned round = 0; round < 2 * ROUNDS; round++) {
		usleep(rand_r(&seed) % 40000); /* spread over the clients' rounds */
		raw_send(fd, 0x600 + 127, ind);
		if (!raw_recv(fd, d, 10000)) {
			atomic_fetch_add(&tally.sess_unexpected, 1);
			continue;
		}
		if (d[0] == 0x80) {
			uint32_t code = (uint32_t)d[4] | (uint32_t)d[5] << 8 |
					(uint32_t)d[6] << 16 | (uint32_t)d[7] << 24;
			if (code == SDO_AB_ROUTE_BUSY) {
				atomic_fetch_add(&tally.sess_busy, 1);
			} else if (code == SDO_AB_NO_RESOURCE) {
				atomic_fetch_add(&tally.sess_no_client, 1);
			} else {
				atomic_fetch_add(&tally.sess_unexpected, 1);
				atomic_store(&tally.sess_last, code);
			}
			continue;
		}
		atomic_fetch_add(&tally.sess_confirmed, 1);
		if (rand_r(&seed) % 2) {
			/* a segmented upload begun, then given up: the lease drains */
			raw_send(fd, 0x600 + 127, up);
			(void)raw_recv(fd, d, 5000);
		}
		raw_send(fd, 0x600 + 127, ab);
	}
	close(fd);
	return NULL;
}

/* Four transfers at once from line `from` to silent nodes of network
 * net: each must end "no answer" (0A000002), none "no free client". */
static void expect_all_clients_lendable(cogw *h, unsigned from, uint16_t net)
{
	uint64_t corr[4];

	for (unsigned i = 0; i < 4; i++) {
		mbx_gw_sdo_req r = {
			.net = net, .sdo = { .node = (uint8_t)(40 + i), .index = 0x1000, .size = 4 }
		};
		TEST_ASSERT_EQUAL_INT(
			0, cogw_send_async(h, from, MBX_CMD_GW_SDO_UPLOAD, &r, sizeof r, &corr[i]));
	}
	for (unsigned i = 0; i < 4; i++) {
		cogw_msg m;
		bool got = false;
		for (int k = 0; k < 100 && !got; k++) {
			TEST_ASSERT_EQUAL_INT(0, cogw_recv(h, &m, 30000));
			got = m.kind == MBX_KIND_RESPONSE && m.corr == corr[i];
			if (got) {
				char why[64];
				snprintf(why, sizeof why,
					 "network %u, node %u: status %d abort %08X", net, 40 + i,
					 m.status, (unsigned)m.abort);
				TEST_ASSERT_EQUAL_HEX32_MESSAGE(SDO_AB_NODE_UNKNOWN, m.abort, why);
			}
			cogw_msg_release(&m);
		}
		TEST_ASSERT_TRUE(got);
	}
}

static unsigned leases_held(cogw *h)
{
	unsigned n = 0;

	for (unsigned i = 0; i < GW_LINES; i++) {
		mbx_gw_status st;
		static mbx_gw_route routes[128];
		size_t nr = 0;
		TEST_ASSERT_EQUAL_INT(0, cogw_gw_routes(h, i, &st, routes, 128, &nr, 20000));
		n += st.leases;
	}
	return n;
}

/* What the mailbox clients met (on failure, what "unexpected" held). */
static void print_tally(void)
{
	printf("routed sessions from vcan0: confirmed %u, refused (routing busy %u, no client "
	       "free %u), unexpected %u (last %08X)\n",
	       atomic_load(&tally.sess_confirmed), atomic_load(&tally.sess_busy),
	       atomic_load(&tally.sess_no_client), atomic_load(&tally.sess_unexpected),
	       atomic_load(&tally.sess_last));
	printf("answered %u, refused (routing busy %u, no client free %u), timed out %u, "
	       "vanished %u\n",
	       atomic_load(&tally.answered), atomic_load(&tally.refused),
	       atomic_load(&tally.no_client), atomic_load(&tally.timed_out),
	       atomic_load(&tally.vanished));
	printf("unexpected %u: registrations failed %u (last %d), sends failed %u (last %d), "
	       "no answer %u, last abort or status %08X (line * 100 + network * 10 + block: "
	       "%03u)\n",
	       atomic_load(&tally.unexpected), atomic_load(&tally.open_failed),
	       atomic_load(&tally.last_open_rc), atomic_load(&tally.send_failed),
	       atomic_load(&tally.last_send_rc), atomic_load(&tally.no_answer),
	       atomic_load(&tally.last_unexpected), atomic_load(&tally.last_where));
}

static void test_routed_transfers_whose_clients_vanish(void)
{
	pthread_t t[CLIENTS], req;

	start_all();
	TEST_ASSERT_EQUAL(0, pthread_create(&req, NULL, giving_up_requester, NULL));
	for (unsigned i = 0; i < CLIENTS; i++)
		TEST_ASSERT_EQUAL(0,
				  pthread_create(&t[i], NULL, client, (void *)(uintptr_t)(i + 1)));
	for (unsigned i = 0; i < CLIENTS; i++)
		pthread_join(t[i], NULL);
	pthread_join(req, NULL);
	print_tally();
	char why[64];
	snprintf(why, sizeof why, "unexpected answers (the last: %08X)",
		 atomic_load(&tally.last_unexpected));
	TEST_ASSERT_EQUAL_UINT_MESSAGE(0, atomic_load(&tally.unexpected), why);
	TEST_ASSERT_EQUAL_UINT(0, atomic_load(&tally.wrong_data));
	TEST_ASSERT_TRUE(atomic_load(&tally.vanished) > 0);
	TEST_ASSERT_TRUE(atomic_load(&tally.answered) > 0);
	TEST_ASSERT_EQUAL_UINT(0, atomic_load(&tally.sess_unexpected));
	TEST_ASSERT_TRUE(atomic_load(&tally.sess_confirmed) > 0);

	/* Nothing left behind: every lease given back (the cancelled
	 * transfers' CLOSE, within a few loop turns), and every line reaches
	 * every network, one transfer at a time. */
	cogw *h = open_client();
	TEST_ASSERT_NOT_NULL(h);
	unsigned held = 1;
	for (int i = 0; i < 100 && (held = leases_held(h)); i++)
		usleep(50000);
	TEST_ASSERT_EQUAL_UINT(0, held);
	/* a server whose transfer a line ended with its own abort frame (a
	 * vanished client's) is not lent for 100 ms more (docs/gateway.md) */
	usleep(300000);
	for (unsigned l = 0; l < GW_LINES; l++)
		for (uint16_t net = 2; net <= 3; net++)
			expect_success(h, l, net, net == 3);
	expect_all_clients_lendable(h, 2, 2);
	expect_all_clients_lendable(h, 0, 3);
	cogw_close(h);
}

/* ---- a requester of its own on vcan0 ----------------------------------------------- */

static struct {
	atomic_uint confirmed, refused, values, segmented, wrong, lost;
	atomic_uint last_wrong; /* first byte of the last wrong answer, or an abort */
} rq;

static int requester_socket(void)
{
	int s = socket(PF_CAN, SOCK_RAW, CAN_RAW);
	struct can_filter f = { .can_id = 0x580u + 127u, .can_mask = CAN_SFF_MASK };
	struct timeval tv = { .tv_sec = 5 };
	struct sockaddr_can a = { .can_family = AF_CAN,
				  .can_ifindex = (int)if_nametoindex("vcan0") };

	if (s < 0 || setsockopt(s, SOL_CAN_RAW, CAN_RAW_FILTER, &f, sizeof f) ||
	    setsockopt(s, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv) ||
	    bind(s, (struct sockaddr *)&a, sizeof a)) {
		if (s >= 0)
			close(s);
		return -1;
	}
	return s;
}

/* One request to the gateway's SDO server, its answer into ans; false when
 * none came (counted). */
static bool ask(int s, const uint8_t req[8], uint8_t ans[8])
{
	struct can_frame f = { .can_id = 0x600u + 127u, .can_dlc = 8 };

	memcpy(f.data, req, 8);
	if (write(s, &f, sizeof f) != (ssize_t)sizeof f ||
	    read(s, &f, sizeof f) != (ssize_t)sizeof f) {
		atomic_fetch_add(&rq.lost, 1);
		return false;
	}
	memcpy(ans, f.data, 8);
	return true;
}

static void wrong(uint8_t first, const uint8_t ans[8])
{
	atomic_fetch_add(&rq.wrong, 1);
	atomic_store(&rq.last_wrong, ans[0] == 0x80 ? (unsigned)co_get_le32(&ans[4]) : first);
}

/* Upload of SHORT_IDX, segment by segment after the initiate. */
static void read_short(int s)
{
	uint8_t req[8] = { 0x40, SHORT_IDX & 0xFF, SHORT_IDX >> 8, 0 }, ans[8];
	uint8_t got[SHORT_LEN];
	unsigned n = 0, toggle = 0;

	if (!ask(s, req, ans))
		return;
	if (ans[0] != 0x41 || co_get_le32(&ans[4]) != SHORT_LEN)
		return wrong(ans[0], ans);
	for (;;) {
		uint8_t seg[8] = { (uint8_t)(0x60 | toggle) };
		if (!ask(s, seg, ans))
			return;
		unsigned len = 7u - ((ans[0] >> 1) & 7u);
		if ((ans[0] & 0xE0) != 0 || (ans[0] & 0x10) != toggle || n + len > SHORT_LEN)
			return wrong(ans[0], ans);
		memcpy(&got[n], &ans[1], len);
		n += len;
		toggle ^= 0x10;
		if (ans[0] & 1)
			break;
	}
	if (n != SHORT_LEN || memcmp(got, domain, SHORT_LEN))
		return wrong(0xDD, ans);
	atomic_fetch_add(&rq.segmented, 1);
}

static void *requester(void *arg)
{
	int s = requester_socket();

	(void)arg;
	if (s < 0) {
		atomic_fetch_add(&rq.lost, 1);
		return NULL;
	}
	for (unsigned round = 0; round < REQ_ROUNDS; round++) {
		uint8_t ind[8] = { 0xE0, 2, 0, DEV_NODE }, ans[8];
		uint8_t up[8] = { 0x40, VALUE_IDX & 0xFF, VALUE_IDX >> 8, 0 };

		if (!ask(s, ind, ans))
			continue;
		if (ans[0] == 0x80) {
			uint32_t ab = co_get_le32(&ans[4]);
			/* the device's server in another line's transfer, or
			 * every client of line 1 lent: what the mailbox clients
			 * explain */
			if (ab == SDO_AB_ROUTE_BUSY || ab == SDO_AB_NO_RESOURCE)
				atomic_fetch_add(&rq.refused, 1);
			else
				wrong(0x80, ans);
			continue;
		}
		if (memcmp(ans, ind, 8) != 0) {
			wrong(ans[0], ans);
			continue;
		}
		/* every second session confirmed reads segmented: both kinds
		 * run however many sessions the mailbox clients leave it */
		if (atomic_fetch_add(&rq.confirmed, 1) % 2 == 1) {
			read_short(s);
			continue;
		}
		if (!ask(s, up, ans))
			continue;
		if (ans[0] == 0x43 && !memcmp(&ans[1], &up[1], 3) && co_get_le32(&ans[4]) == VALUE)
			atomic_fetch_add(&rq.values, 1);
		else
			wrong(ans[0], ans);
	}
	close(s);
	return NULL;
}

static void test_routed_sessions_send_across_while_hops_run(void)
{
	pthread_t t[CLIENTS], r;
	gw_line_counters c0, c1;

	memset(&tally, 0, sizeof tally);
	start_all();
	TEST_ASSERT_EQUAL(0, pthread_create(&r, NULL, requester, NULL));
	for (unsigned i = 0; i < CLIENTS; i++)
		TEST_ASSERT_EQUAL(0,
				  pthread_create(&t[i], NULL, client, (void *)(uintptr_t)(i + 7)));
	pthread_join(r, NULL);
	for (unsigned i = 0; i < CLIENTS; i++)
		pthread_join(t[i], NULL);
	gw_line_counters_get(g, 0, &c0);
	gw_line_counters_get(g, 1, &c1);
	printf("requester: confirmed %u, refused %u, values %u, segmented %u, wrong %u (last "
	       "%08X), lost %u; sent across by line 0 %llu, by line 1 %llu\n",
	       atomic_load(&rq.confirmed), atomic_load(&rq.refused), atomic_load(&rq.values),
	       atomic_load(&rq.segmented), atomic_load(&rq.wrong), atomic_load(&rq.last_wrong),
	       atomic_load(&rq.lost), (unsigned long long)c0.sdo_across,
	       (unsigned long long)c1.sdo_across);
	print_tally();
	TEST_ASSERT_EQUAL_UINT(0, atomic_load(&rq.wrong));
	TEST_ASSERT_EQUAL_UINT(0, atomic_load(&tally.unexpected));
	TEST_ASSERT_EQUAL_UINT(0, atomic_load(&tally.wrong_data));
	TEST_ASSERT_TRUE(atomic_load(&rq.values) > 0);
	TEST_ASSERT_TRUE(atomic_load(&rq.segmented) > 0);
	/* both directions went across: requests by line 0 on vcan1, answers
	 * by line 1 on vcan0 */
	TEST_ASSERT_TRUE(c0.sdo_across > 0);
	TEST_ASSERT_TRUE(c1.sdo_across > 0);
}

/* Five lines and the client threads' handles all run as one user here:
 * a vanished handle's queues stay charged to it until the lines have
 * closed their descriptors of them, so the default 800 KiB of queue memory
 * can run out in a burst of vanishing (COGW_E_QUEUE_LIMIT, what a real
 * user would be told too). The test is about routing: give it room. */
static void room_for_queues(void)
{
	struct rlimit r = { RLIM_INFINITY, RLIM_INFINITY };

	if (setrlimit(RLIMIT_MSGQUEUE, &r) != 0 && getrlimit(RLIMIT_MSGQUEUE, &r) == 0) {
		r.rlim_cur = r.rlim_max;
		setrlimit(RLIMIT_MSGQUEUE, &r);
	}
}

int main(void)
{
	room_for_queues();
	UNITY_BEGIN();
	RUN_TEST(test_routed_transfers_whose_clients_vanish);
	RUN_TEST(test_routed_sessions_send_across_while_hops_run);
	return UNITY_END();
}
