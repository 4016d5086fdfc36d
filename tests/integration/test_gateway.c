/* SPDX-License-Identifier: MIT */
/*
 * The CiA 302-7 gateway with the real daemon, cosim devices and raw CAN on
 * three vcan lines (spec 002 scenarios 60-63):
 * - a requester on vcan0 that speaks the network indication (the core's
 *   own SDO client driven over a raw socket, after a hand-made indication
 *   frame) reads and writes a device on vcan2 in every SDO mode, byte-exact;
 * - refusals: unknown network at once, a silent target node, a loop;
 * - EMCY routing by 1F2Fh bits (set: forwarded to vcan1 and vcan2 in the
 *   convention's encoding; cleared: nowhere);
 * - PDO forwarding of B000h: an RPDO on vcan0 comes out of the event-driven
 *   TPDO on vcan1 at once and of the synchronous one after the next SYNC;
 *   a burst loses no last value.
 * All in one binary: one VM boot for the lot.
 */
#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cjson/cJSON.h>
#include <linux/can.h>

#include "unity.h"

#include "core/co.h"
#include "core/sdo_client.h"
#include "gateway/convention.h"
#include "mailbox/cogw.h"
#include "tests/integration/support/daemon.h"

#define INSTANCE "gwtest"
#define GW_NODE 127
#define TGT_NODE 5  /* device on vcan2 (network 3) */
#define EMCY_NODE 7 /* device on vcan0 (network 1) */
#define DOMAIN_IDX 0x2200u
#define DOMAIN_MAX (1024u * 1024u)
/* The largest routed transfer here: with the ASan daemon and device in the
 * emulated VM a 1 MiB block transfer takes minutes; 1 MiB each way runs in
 * bench_vcan_gateway (release build), checked byte for byte there too. */
#define BIG (256u * 1024u)

static const char config_json[] =
	"{\n"
	" \"version\": 1,\n"
	" \"mailbox\": {\"instance\": \"" INSTANCE "\"},\n"
	" \"gateway\": {\"process_image\": [{\"index\": \"0xB000\", \"type\": \"UNSIGNED32\",\n"
	"               \"access\": \"rw\", \"pdo\": true}]},\n"
	" \"lines\": [\n"
	"  {\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127, \"network_id\": 1,\n"
	"   \"sdo_timeout_ms\": 3000, \"heartbeat_ms\": 0, \"rpdos\": 1,\n"
	"   \"values\": [\n"
	"    {\"index\": \"0x1400\", \"sub\": 1, \"value\": \"0x181\"},\n"
	"    {\"index\": \"0x1600\", \"sub\": 1, \"value\": \"0xB0000020\"},\n"
	"    {\"index\": \"0x1600\", \"sub\": 0, \"value\": 1},\n"
	"    {\"index\": \"0x1F2F\", \"sub\": 7, \"value\": 6}]},\n"
	"  {\"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": 127, \"network_id\": 2,\n"
	"   \"sdo_timeout_ms\": 3000, \"heartbeat_ms\": 0, \"tpdos\": 2, \"sync_period_us\": "
	"200000,\n"
	"   \"values\": [\n"
	"    {\"index\": \"0x1800\", \"sub\": 1, \"value\": \"0x1FF\"},\n"
	"    {\"index\": \"0x1A00\", \"sub\": 1, \"value\": \"0xB0000020\"},\n"
	"    {\"index\": \"0x1A00\", \"sub\": 0, \"value\": 1},\n"
	"    {\"index\": \"0x1801\", \"sub\": 1, \"value\": \"0x2FF\"},\n"
	"    {\"index\": \"0x1801\", \"sub\": 2, \"value\": 1},\n"
	"    {\"index\": \"0x1A01\", \"sub\": 1, \"value\": \"0xB0000020\"},\n"
	"    {\"index\": \"0x1A01\", \"sub\": 0, \"value\": 1}]},\n"
	"  {\"interface\": \"vcan2\", \"bitrate\": 1000000, \"node_id\": 127, \"network_id\": 3,\n"
	"   \"sdo_timeout_ms\": 3000, \"heartbeat_ms\": 0}\n"
	" ]\n"
	"}\n";

static daemon_run dmn, dmn_b; /* dmn_b: the second router of the multi-hop test */
static cosim_run sim_tgt, sim_emcy;
static int fd0, fd1, fd2; /* raw sockets on vcan0..2 */

/* ---- the requester: a core SDO client on vcan0 over a raw socket ------------------------ */

static co_node *req;
static co_od *req_od;
static bool req_done;
static co_ev_sdo_cli req_result;

static uint64_t now_us(void)
{
	struct timespec ts;

	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static int req_send(void *ctx, const co_frame *f)
{
	(void)ctx;
	return can_send_std(fd0, f->id, f->data, f->len);
}

static void req_event(void *ctx, const co_event *ev)
{
	(void)ctx;
	if (ev->kind == CO_EV_SDO_CLIENT_DONE) {
		req_result = ev->u.sdo_cli;
		req_done = true;
	}
}

/* Feed vcan0 frames to the requester until it completed or timeout_ms. */
static void req_run(int timeout_ms)
{
	uint64_t until = now_us() + (uint64_t)timeout_ms * 1000u;

	while (!req_done && now_us() < until) {
		struct pollfd p = { .fd = fd0, .events = POLLIN };
		uint64_t dl = co_node_next_deadline_us(req), t = now_us();
		int wait = 50;

		if (dl != CO_NO_DEADLINE && dl > t && (dl - t) / 1000u < 50u)
			wait = (int)((dl - t) / 1000u) + 1;
		if (poll(&p, 1, wait) > 0) {
			struct can_frame cf;
			if (read(fd0, &cf, sizeof cf) == (ssize_t)sizeof cf &&
			    !(cf.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG))) {
				co_frame f;
				co_frame_init(&f, cf.can_id, cf.len);
				memcpy(f.data, cf.data, 8);
				co_node_recv(req, &f, now_us());
			}
		}
		co_node_tick(req, now_us());
	}
}

/* Empty a raw socket. */
static void drain(int fd)
{
	struct can_frame cf;
	struct pollfd p = { .fd = fd, .events = POLLIN };

	while (poll(&p, 1, 0) > 0 && read(fd, &cf, sizeof cf) > 0)
		;
}

/* Send the indication for (net, node); return the gateway's answer. */
static void indicate(uint16_t net, uint8_t node, uint8_t answer[8])
{
	uint8_t d[8];

	gw_netind_encode(d, (gw_netind){ net, node });
	drain(fd0);
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd0, 0x600 + GW_NODE, d, 8));
	TEST_ASSERT_EQUAL_INT_MESSAGE(8, can_wait_id(fd0, 0x580 + GW_NODE, answer, 10000),
				      "no answer to the network indication");
}

static void expect_confirm(uint16_t net, uint8_t node)
{
	uint8_t a[8], want[8];

	indicate(net, node, a);
	gw_netind_encode(want, (gw_netind){ net, node });
	TEST_ASSERT_EQUAL_HEX8_ARRAY(want, a, 8);
}

static const co_ev_sdo_cli *routed(const sdo_client_req *r)
{
	char msg[96];

	snprintf(msg, sizeof msg, "routed %s %04X:%02X, %u bytes, mode %u did not complete",
		 r->upload ? "upload" : "download", r->index, r->sub, r->upload ? r->cap : r->size,
		 r->mode);
	req_done = false;
	expect_confirm(3, TGT_NODE);
	TEST_ASSERT_EQUAL_INT(0, sdo_client_submit(req, 0, r, now_us()));
	req_run(240000);
	TEST_ASSERT_TRUE_MESSAGE(req_done, msg);
	return &req_result;
}

static uint8_t big_in[DOMAIN_MAX], big_out[DOMAIN_MAX];

/* ---- set-up ------------------------------------------------------------------------------- */

static void write_device(const char *dst)
{
	FILE *f = fopen("etc/devices/sti-pressure.json", "r");
	static char text[65536];
	size_t n;
	cJSON *root, *objects, *o;
	char *out;

	TEST_ASSERT_NOT_NULL(f);
	n = fread(text, 1, sizeof text - 1, f);
	fclose(f);
	text[n] = '\0';
	root = cJSON_Parse(text);
	TEST_ASSERT_NOT_NULL(root);
	objects = cJSON_GetObjectItemCaseSensitive(root, "objects");
	o = cJSON_CreateObject();
	cJSON_AddStringToObject(o, "index", "0x2200");
	cJSON_AddStringToObject(o, "name", "test domain");
	cJSON_AddStringToObject(o, "type", "DOMAIN");
	cJSON_AddStringToObject(o, "access", "rw");
	cJSON_AddNumberToObject(o, "max_size", DOMAIN_MAX);
	cJSON_AddItemToArray(objects, o);
	out = cJSON_Print(root);
	TEST_ASSERT_EQUAL_INT(0, write_text_file(dst, out));
	free(out);
	cJSON_Delete(root);
}

static void nmt_start_all_daemon_nodes(void)
{
	uint8_t start[2] = { 0x01, GW_NODE };

	can_send_std(fd0, 0x000, start, 2);
	can_send_std(fd1, 0x000, start, 2);
	can_send_std(fd2, 0x000, start, 2);
	sleep_ms(300);
}

/* The single daemon of most tests: three lines, the target device on vcan2,
 * the EMCY producer on vcan0. */
static void start_single(void)
{
	char dev[160], dev_tgt[200], dev_emcy[200];
	static const char *const slow_vm[] = { "--sdo-timeout", "10000", NULL };

	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = config_json,
								    .instance = INSTANCE,
								    .n_lines = 3,
								    .notify = true,
								    .drop_notify = true }));
	snprintf(dev, sizeof dev, "%s/device.json", dmn.dir);
	write_device(dev);
	snprintf(dev_tgt, sizeof dev_tgt, "%s:%d", dev, TGT_NODE);
	snprintf(dev_emcy, sizeof dev_emcy, "%s:%d", dev, EMCY_NODE);
	const char *d2[] = { dev_tgt, NULL }, *d0[] = { dev_emcy, NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim_tgt, dmn.dir, 2, d2, slow_vm));
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim_emcy, dmn.dir, 0, d0, slow_vm));
}

void setUp(void)
{
	co_node_config rc = { .node_id = 1,
			      .sdo_client_count = 1,
			      .sdo_client_timeout_ms = 10000,
			      .send = req_send,
			      .event = req_event };

	fd0 = can_open_raw("vcan0");
	fd1 = can_open_raw("vcan1");
	fd2 = can_open_raw("vcan2");
	TEST_ASSERT_TRUE(fd0 >= 0 && fd1 >= 0 && fd2 >= 0);
	TEST_ASSERT_EQUAL_INT(0, co_od_create(&req_od, 16));
	rc.od = req_od;
	TEST_ASSERT_EQUAL_INT(0, co_node_create(&req, &rc));
}

void tearDown(void)
{
	co_node_destroy(req);
	co_od_destroy(req_od);
	req = NULL;
	req_od = NULL;
	close(fd0);
	close(fd1);
	close(fd2);
	cosim_stop(&sim_tgt, 3000);
	cosim_stop(&sim_emcy, 3000);
	daemon_stop(&dmn, 10000);
	daemon_cleanup(&dmn);
	daemon_stop(&dmn_b, 10000);
	daemon_cleanup(&dmn_b);
}

/* ---- SDO routing (scenario 60) -------------------------------------------------------------- */

static void fill(uint8_t *buf, size_t len, unsigned seed)
{
	for (size_t i = 0; i < len; i++)
		buf[i] = (uint8_t)(seed * 131u + i * 7u + (i >> 8) * 13u + 1u);
}

static void test_routed_sdo_every_mode_byte_exact(void)
{
	static const uint32_t sizes[] = { 1, 4, 7, 8, 100, 889, 890, 20000 };
	static const uint8_t modes[] = { SDO_MODE_EXPEDITED, SDO_MODE_SEGMENTED, SDO_MODE_BLOCK };
	uint8_t *in = big_in, *out = big_out;
	uint8_t id[4];
	char msg[64];
	const co_ev_sdo_cli *r;

	start_single();

	/* expedited read of 1000h on the device behind the gateway */
	r = routed(&(sdo_client_req){
		.upload = true, .node_id = GW_NODE, .index = 0x1000, .buf = id, .cap = 4 });
	TEST_ASSERT_EQUAL_HEX32(0, r->abort);
	TEST_ASSERT_EQUAL_HEX32(0x00040194, co_get_le32(id));
	for (size_t m = 0; m < sizeof modes; m++) {
		for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
			uint32_t size = sizes[i];
			snprintf(msg, sizeof msg, "%u bytes, mode %u", size, modes[m]);
			fill(in, size, (unsigned)(m * 10 + i));
			r = routed(&(sdo_client_req){ .node_id = GW_NODE,
						      .index = DOMAIN_IDX,
						      .mode = modes[m],
						      .data = in,
						      .size = size });
			TEST_ASSERT_EQUAL_HEX32_MESSAGE(0, r->abort, msg);
			memset(out, 0, size);
			r = routed(&(sdo_client_req){ .upload = true,
						      .node_id = GW_NODE,
						      .index = DOMAIN_IDX,
						      .mode = modes[m],
						      .buf = out,
						      .cap = DOMAIN_MAX,
						      .size = size });
			TEST_ASSERT_EQUAL_HEX32_MESSAGE(0, r->abort, msg);
			TEST_ASSERT_EQUAL_UINT32_MESSAGE(size, r->size, msg);
			TEST_ASSERT_EQUAL_MEMORY_MESSAGE(in, out, size, msg);
		}
	}
	/* BIG by block, both ways */
	fill(in, BIG, 99);
	r = routed(&(sdo_client_req){ .node_id = GW_NODE,
				      .index = DOMAIN_IDX,
				      .mode = SDO_MODE_BLOCK,
				      .data = in,
				      .size = BIG });
	TEST_ASSERT_EQUAL_HEX32(0, r->abort);
	memset(out, 0, BIG);
	r = routed(&(sdo_client_req){ .upload = true,
				      .node_id = GW_NODE,
				      .index = DOMAIN_IDX,
				      .mode = SDO_MODE_BLOCK,
				      .buf = out,
				      .cap = DOMAIN_MAX,
				      .size = BIG });
	TEST_ASSERT_EQUAL_HEX32(0, r->abort);
	TEST_ASSERT_EQUAL_UINT32(BIG, r->size);
	TEST_ASSERT_EQUAL_MEMORY(in, out, BIG);
}

static void test_refusals(void)
{
	uint8_t a[8];
	uint64_t t0;

	start_single();

	/* unknown network: at once */
	t0 = mono_ms();
	indicate(9, TGT_NODE, a);
	TEST_ASSERT_TRUE_MESSAGE(mono_ms() - t0 < 1000, "refusal took a timeout");
	TEST_ASSERT_EQUAL_HEX8(0x80, a[0]);
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, co_get_le32(&a[4]));
	/* our own network (the request's way back) */
	indicate(1, EMCY_NODE, a);
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, co_get_le32(&a[4]));
	/* a node that never answers: the initiate gets "no answer" */
	expect_confirm(3, 99);
	uint8_t init[8] = { 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0 };
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd0, 0x600 + GW_NODE, init, 8));
	TEST_ASSERT_EQUAL_INT(8, can_wait_id(fd0, 0x580 + GW_NODE, a, 10000));
	TEST_ASSERT_EQUAL_HEX8(0x80, a[0]);
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NO_ANSWER, co_get_le32(&a[4]));
	/* the gateway still routes afterwards */
	const co_ev_sdo_cli *r;
	uint8_t id[4];
	r = routed(&(sdo_client_req){
		.upload = true, .node_id = GW_NODE, .index = 0x1000, .buf = id, .cap = 4 });
	TEST_ASSERT_EQUAL_HEX32(0, r->abort);
}

static void test_requester_vanishing_mid_block_releases_the_session(void)
{
	uint8_t a[8];
	uint8_t init[8] = { 0xC6, 0x00, 0x22, 0x00, 0x00, 0x10, 0, 0 }; /* 4096 bytes */
	uint8_t seg[8] = { 0x01, 1, 2, 3, 4, 5, 6, 7 };

	start_single();

	expect_confirm(3, TGT_NODE);
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd0, 0x600 + GW_NODE, init, 8));
	TEST_ASSERT_EQUAL_INT(8, can_wait_id(fd0, 0x580 + GW_NODE, a, 10000));
	TEST_ASSERT_EQUAL_HEX8(0xA0, a[0] & 0xE3);
	for (uint8_t i = 1; i <= 3; i++) {
		seg[0] = i;
		can_send_std(fd0, 0x600 + GW_NODE, seg, 8);
	}
	/* ... and silence: the gateway aborts both ends after its timeout */
	TEST_ASSERT_EQUAL_INT(8, can_wait_id(fd0, 0x580 + GW_NODE, a, 15000));
	TEST_ASSERT_EQUAL_HEX8(0x80, a[0]);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_TIMEOUT, co_get_le32(&a[4]));
	/* the channel and the lease are free again */
	const co_ev_sdo_cli *r;
	uint8_t id[4];
	r = routed(&(sdo_client_req){
		.upload = true, .node_id = GW_NODE, .index = 0x1000, .buf = id, .cap = 4 });
	TEST_ASSERT_EQUAL_HEX32(0, r->abort);
}

/* ---- EMCY routing (scenario 61) ------------------------------------------------------------- */

static void test_emcy_routing_follows_1f2f(void)
{
	uint8_t d[8];
	const co_ev_sdo_cli *r;
	uint8_t zero[4] = { 0 };

	start_single();

	drain(fd1);
	drain(fd2);
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim_emcy, "emcy 0x1234", NULL, 0, 5000));
	TEST_ASSERT_EQUAL_INT(8, can_wait_id(fd1, 0x80 + GW_NODE, d, 5000));
	TEST_ASSERT_EQUAL_HEX16(GW_EMCY_FWD_CODE, co_get_le16(&d[0]));
	TEST_ASSERT_EQUAL_HEX16(1, co_get_le16(&d[3])); /* from network 1 */
	TEST_ASSERT_EQUAL_HEX8(EMCY_NODE, d[5]);
	TEST_ASSERT_EQUAL_HEX16(0x1234, co_get_le16(&d[6]));
	TEST_ASSERT_EQUAL_INT(8, can_wait_id(fd2, 0x80 + GW_NODE, d, 5000));
	TEST_ASSERT_EQUAL_HEX16(0x1234, co_get_le16(&d[6]));

	/* 1F2Fh:7 = 0 over SDO on vcan0 (plain, not routed) */
	req_done = false;
	TEST_ASSERT_EQUAL_INT(0, sdo_client_submit(req, 0,
						   &(sdo_client_req){ .node_id = GW_NODE,
								      .index = 0x1F2F,
								      .sub = EMCY_NODE,
								      .data = zero,
								      .size = 4 },
						   now_us()));
	req_run(10000);
	r = &req_result;
	TEST_ASSERT_TRUE(req_done);
	TEST_ASSERT_EQUAL_HEX32(0, r->abort);
	drain(fd1);
	drain(fd2);
	TEST_ASSERT_EQUAL_INT(0, cosim_ctl(&sim_emcy, "emcy 0x4321", NULL, 0, 5000));
	TEST_ASSERT_EQUAL_INT(-ETIMEDOUT, can_wait_id(fd1, 0x80 + GW_NODE, d, 1500));
	TEST_ASSERT_EQUAL_INT(-ETIMEDOUT, can_wait_id(fd2, 0x80 + GW_NODE, d, 500));
}

/* ---- PDO forwarding (scenario 62) ------------------------------------------------------------ */

static void test_pdo_forwarding(void)
{
	uint8_t v[4] = { 0x11, 0x22, 0x33, 0x44 }, d[8];
	unsigned got = 0;
	uint32_t last = 0;

	start_single();

	nmt_start_all_daemon_nodes();
	drain(fd1);
	TEST_ASSERT_EQUAL_INT(0, can_send_std(fd0, 0x181, v, 4));
	/* event-driven TPDO 1 on vcan1: at once */
	TEST_ASSERT_EQUAL_INT(4, can_wait_id(fd1, 0x1FF, d, 3000));
	TEST_ASSERT_EQUAL_HEX8_ARRAY(v, d, 4);
	/* synchronous TPDO 2 (TT 1): after the next SYNC, same value */
	TEST_ASSERT_EQUAL_INT(4, can_wait_id(fd1, 0x2FF, d, 3000));
	TEST_ASSERT_EQUAL_HEX8_ARRAY(v, d, 4);

	/* a burst of 1000: the last value always comes through. The receiving
	 * socket must hold what arrives while this thread still sends (its
	 * default buffer drops the newest frames, not the gateway). */
	int big = 4 * 1024 * 1024;
	setsockopt(fd1, SOL_SOCKET, SO_RCVBUF, &big, sizeof big);
	drain(fd1);
	for (uint32_t i = 1; i <= 1000; i++) {
		uint8_t b[4];
		co_put_le32(b, 0xAB000000u + i);
		while (can_send_std(fd0, 0x181, b, 4) != 0)
			sleep_ms(1);
	}
	for (;;) {
		if (can_wait_id(fd1, 0x1FF, d, 3000) != 4)
			break;
		got++;
		last = co_get_le32(d);
		if (last == 0xAB000000u + 1000)
			break;
	}
	printf("burst: 1000 RPDOs on vcan0, %u event-driven TPDOs on vcan1, last %08X\n", got,
	       last);
	TEST_ASSERT_EQUAL_HEX32(0xAB000000u + 1000, last);
}

/* ---- mailbox clients (libcogw) ------------------------------------------------------------ */

static void test_mailbox_client_reaches_any_network(void)
{
	cogw *h = NULL;
	cogw_options o = { .instance = INSTANCE, .timeout_ms = 30000 };
	uint8_t buf[64], data[40];
	size_t len = 0;
	uint32_t abort = 0;
	mbx_gw_status st;
	mbx_gw_route routes[128];
	size_t n = 0;

	start_single();

	TEST_ASSERT_EQUAL_INT(0, cogw_open_opts(&h, &o));
	/* asked on line 0, node 5 of network 3 (attached to line 2) */
	TEST_ASSERT_EQUAL_INT(0, cogw_sdo_read_net(h, 0, 3, TGT_NODE, 0x1000, 0, NULL, buf,
						   sizeof buf, &len, 30000, &abort));
	TEST_ASSERT_EQUAL_UINT(4, len);
	TEST_ASSERT_EQUAL_HEX32(0x00040194, co_get_le32(buf));
	fill(data, sizeof data, 7);
	TEST_ASSERT_EQUAL_INT(0, cogw_sdo_write_net(h, 1, 3, TGT_NODE, DOMAIN_IDX, 0, NULL, data,
						    sizeof data, 30000, &abort));
	TEST_ASSERT_EQUAL_INT(0, cogw_sdo_read_net(h, 2, 3, TGT_NODE, DOMAIN_IDX, 0, NULL, buf,
						   sizeof buf, &len, 30000, &abort));
	TEST_ASSERT_EQUAL_UINT(sizeof data, len);
	TEST_ASSERT_EQUAL_MEMORY(data, buf, sizeof data);
	/* no route */
	TEST_ASSERT_EQUAL_INT(COGW_E_ABORT,
			      cogw_sdo_read_net(h, 0, 9, TGT_NODE, 0x1000, 0, NULL, buf, sizeof buf,
						&len, 30000, &abort));
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, abort);
	/* the gateway event class: a refused indication on line 0 */
	TEST_ASSERT_EQUAL_INT(0, cogw_subscribe(h, 0, MBX_EVC_GW, NULL, 0, 30000));
	uint8_t a[8];
	indicate(9, TGT_NODE, a);
	cogw_msg ev;
	bool seen = false;
	for (int i = 0; i < 20 && !seen; i++) {
		if (cogw_recv(h, &ev, 1000) != 0)
			continue;
		if (ev.kind == MBX_KIND_EVENT && ev.code == MBX_EV_GW_SDO) {
			mbx_ev_gw_sdo e;
			TEST_ASSERT_EQUAL_UINT(sizeof e, ev.len);
			memcpy(&e, ev.data, sizeof e);
			TEST_ASSERT_EQUAL_UINT(9, e.net);
			TEST_ASSERT_EQUAL_UINT(3, e.outcome);
			TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, e.abort);
			TEST_ASSERT_EQUAL_UINT(0xFF, e.target_line);
			seen = true;
		}
		cogw_msg_release(&ev);
	}
	TEST_ASSERT_TRUE_MESSAGE(seen, "no gateway event for the refused indication");
	/* the routing table with its counters */
	TEST_ASSERT_EQUAL_INT(0, cogw_gw_routes(h, 0, &st, routes, 128, &n, 30000));
	TEST_ASSERT_EQUAL_UINT(1, st.network_id);
	TEST_ASSERT_TRUE(n >= 3);
	TEST_ASSERT_EQUAL_UINT(1, routes[0].net);
	TEST_ASSERT_EQUAL_UINT(1, routes[0].kind);
	TEST_ASSERT_EQUAL_UINT(3, routes[2].net);
	TEST_ASSERT_EQUAL_UINT(2, routes[2].line);
	cogw_close(h);
}

/* ---- multi-hop: two daemons (A on vcan0+vcan1, B on vcan1+vcan2) ------------------------------ */

static const char config_a[] =
	"{\"mailbox\": {\"instance\": \"gwA\"},\n"
	" \"gateway\": {\"routes\": [{\"network\": 3, \"line\": 1, \"router\": 126},\n"
	"                           {\"network\": 9, \"line\": 1, \"router\": 126}]},\n"
	" \"lines\": [\n"
	"  {\"interface\": \"vcan0\", \"bitrate\": 1000000, \"node_id\": 127, \"network_id\": 1,\n"
	"   \"sdo_timeout_ms\": 3000, \"heartbeat_ms\": 0},\n"
	"  {\"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": 127, \"network_id\": 2,\n"
	"   \"sdo_timeout_ms\": 3000, \"heartbeat_ms\": 0}]}\n";

static const char config_b[] =
	"{\"mailbox\": {\"instance\": \"gwB\"},\n"
	" \"gateway\": {\"routes\": [{\"network\": 1, \"line\": 0, \"router\": 127},\n"
	"                           {\"network\": 9, \"line\": 0, \"router\": 127}]},\n"
	" \"lines\": [\n"
	"  {\"interface\": \"vcan1\", \"bitrate\": 1000000, \"node_id\": 126, \"network_id\": 2,\n"
	"   \"sdo_timeout_ms\": 3000, \"heartbeat_ms\": 0},\n"
	"  {\"interface\": \"vcan2\", \"bitrate\": 1000000, \"node_id\": 127, \"network_id\": 3,\n"
	"   \"sdo_timeout_ms\": 3000, \"heartbeat_ms\": 0}]}\n";

static void test_multi_hop_through_two_daemons(void)
{
	static const char *const slow_vm[] = { "--sdo-timeout", "10000", NULL };
	char dev[160], dev_tgt[200];
	uint8_t id[4], a[8], buf[64];
	uint8_t *in = big_in, *out = big_out;
	const co_ev_sdo_cli *r;
	cogw *h = NULL;
	cogw_options o = { .instance = "gwA", .timeout_ms = 30000 };
	size_t len = 0;
	uint32_t abort = 0;

	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn, &(daemon_opts){ .config_json = config_a,
								    .instance = "gwA",
								    .n_lines = 2,
								    .notify = true,
								    .drop_notify = true }));
	TEST_ASSERT_EQUAL_INT(0, daemon_start(&dmn_b, &(daemon_opts){ .config_json = config_b,
								      .instance = "gwB",
								      .n_lines = 2,
								      .notify = true,
								      .drop_notify = true }));
	snprintf(dev, sizeof dev, "%s/device.json", dmn_b.dir);
	write_device(dev);
	snprintf(dev_tgt, sizeof dev_tgt, "%s:%d", dev, TGT_NODE);
	const char *d2[] = { dev_tgt, NULL };
	TEST_ASSERT_EQUAL_INT(0, cosim_start(&sim_tgt, dmn_b.dir, 2, d2, slow_vm));

	/* a request entering on vcan0 reaches node 5 on vcan2 through A and B */
	r = routed(&(sdo_client_req){
		.upload = true, .node_id = GW_NODE, .index = 0x1000, .buf = id, .cap = 4 });
	TEST_ASSERT_EQUAL_HEX32(0, r->abort);
	TEST_ASSERT_EQUAL_HEX32(0x00040194, co_get_le32(id));
	fill(in, 4000, 3);
	r = routed(&(sdo_client_req){ .node_id = GW_NODE,
				      .index = DOMAIN_IDX,
				      .mode = SDO_MODE_BLOCK,
				      .data = in,
				      .size = 4000 });
	TEST_ASSERT_EQUAL_HEX32(0, r->abort);
	r = routed(&(sdo_client_req){ .upload = true,
				      .node_id = GW_NODE,
				      .index = DOMAIN_IDX,
				      .mode = SDO_MODE_SEGMENTED,
				      .buf = out,
				      .cap = 4000 });
	TEST_ASSERT_EQUAL_HEX32(0, r->abort);
	TEST_ASSERT_EQUAL_UINT32(4000, r->size);
	TEST_ASSERT_EQUAL_MEMORY(in, out, 4000);

	/* a loop (A sends network 9 to B, B back to A) is refused by B */
	indicate(9, TGT_NODE, a);
	TEST_ASSERT_EQUAL_HEX8(0x80, a[0]);
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, co_get_le32(&a[4]));

	/* a mailbox client of A reaches the same node */
	TEST_ASSERT_EQUAL_INT(0, cogw_open_opts(&h, &o));
	TEST_ASSERT_EQUAL_INT(0, cogw_sdo_read_net(h, 0, 3, TGT_NODE, 0x1000, 0, NULL, buf,
						   sizeof buf, &len, 30000, &abort));
	TEST_ASSERT_EQUAL_HEX32(0x00040194, co_get_le32(buf));
	TEST_ASSERT_EQUAL_INT(COGW_E_ABORT,
			      cogw_sdo_read_net(h, 0, 9, TGT_NODE, 0x1000, 0, NULL, buf, sizeof buf,
						&len, 30000, &abort));
	TEST_ASSERT_EQUAL_HEX32(GW_AB_NET_UNKNOWN, abort);
	cogw_close(h);
}

/* ---- 1F2Ch/1F2Fh writable over SDO and the mailbox, kept by 1010h (scenario 63) ------------ */

static void test_routes_written_and_saved_survive_a_restart(void)
{
	cogw *h = NULL;
	cogw_options o = { .instance = INSTANCE, .timeout_ms = 30000 };
	uint8_t v[4], b[8];
	size_t len = 0;
	uint32_t abort = 0;
	mbx_gw_status st;
	mbx_gw_route routes[128];
	size_t n = 0;

	start_single();
	/* over SDO on vcan0: network 20 behind router 33 on line 2 */
	co_put_le32(v, 0x2103);
	req_done = false;
	TEST_ASSERT_EQUAL_INT(0, sdo_client_submit(req, 0,
						   &(sdo_client_req){ .node_id = GW_NODE,
								      .index = 0x1F2C,
								      .sub = 20,
								      .data = v,
								      .size = 4 },
						   now_us()));
	req_run(10000);
	TEST_ASSERT_TRUE(req_done);
	TEST_ASSERT_EQUAL_HEX32(0, req_result.abort);
	/* a line that does not exist is refused */
	co_put_le32(v, 0x0004);
	req_done = false;
	TEST_ASSERT_EQUAL_INT(0, sdo_client_submit(req, 0,
						   &(sdo_client_req){ .node_id = GW_NODE,
								      .index = 0x1F2C,
								      .sub = 21,
								      .data = v,
								      .size = 4 },
						   now_us()));
	req_run(10000);
	TEST_ASSERT_EQUAL_HEX32(SDO_AB_VALUE, req_result.abort);
	/* over the mailbox: node 5's EMCYs to network 3 */
	TEST_ASSERT_EQUAL_INT(0, cogw_open_opts(&h, &o));
	co_put_le32(v, 0x4);
	TEST_ASSERT_EQUAL_INT(0, cogw_od_write(h, 0, 0x1F2F, 5, v, 4, 30000, &abort));
	TEST_ASSERT_EQUAL_INT(0, cogw_gw_routes(h, 0, &st, routes, 128, &n, 30000));
	bool found = false;
	for (size_t i = 0; i < n; i++)
		found = found ||
			(routes[i].net == 20 && routes[i].kind == 2 && routes[i].router == 33);
	TEST_ASSERT_TRUE_MESSAGE(found, "the new route is not in the compiled table");
	/* save (1010h:1), restart on the same state directory */
	TEST_ASSERT_EQUAL_INT(0, cogw_store(h, 0, 1, 30000));
	cogw_close(h);
	h = NULL;
	daemon_stop(&dmn, 10000);
	TEST_ASSERT_EQUAL_INT(0,
			      daemon_start(&dmn_b, &(daemon_opts){ .config_json = config_json,
								   .instance = INSTANCE,
								   .n_lines = 3,
								   .notify = true,
								   .drop_notify = true,
								   .state_dir = dmn.state_dir }));
	TEST_ASSERT_EQUAL_INT(0, cogw_open_opts(&h, &o));
	TEST_ASSERT_EQUAL_INT(0, cogw_od_read(h, 0, 0x1F2C, 20, b, sizeof b, &len, 30000, &abort));
	TEST_ASSERT_EQUAL_HEX32(0x2103, co_get_le32(b));
	TEST_ASSERT_EQUAL_INT(0, cogw_od_read(h, 0, 0x1F2F, 5, b, sizeof b, &len, 30000, &abort));
	TEST_ASSERT_EQUAL_HEX32(0x4, co_get_le32(b));
	TEST_ASSERT_EQUAL_INT(0, cogw_gw_routes(h, 0, &st, routes, 128, &n, 30000));
	found = false;
	for (size_t i = 0; i < n; i++)
		found = found || (routes[i].net == 20 && routes[i].kind == 2);
	TEST_ASSERT_TRUE_MESSAGE(found, "the saved route is not compiled after the restart");
	cogw_close(h);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_routed_sdo_every_mode_byte_exact);
	RUN_TEST(test_refusals);
	RUN_TEST(test_requester_vanishing_mid_block_releases_the_session);
	RUN_TEST(test_emcy_routing_follows_1f2f);
	RUN_TEST(test_pdo_forwarding);
	RUN_TEST(test_mailbox_client_reaches_any_network);
	RUN_TEST(test_multi_hop_through_two_daemons);
	RUN_TEST(test_routes_written_and_saved_survive_a_restart);
	return UNITY_END();
}
