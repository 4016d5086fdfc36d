/* Mailbox wire format (mailbox/proto.c): header round trip byte by byte,
 * one refusal per header field and per payload field, names, queue names,
 * raw filters, event validation and the system-limit message. Pure codec:
 * no queues here (tests/integration/test_mbx_server.c has those). */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "mailbox/proto.h"
#include "unity.h"

static uint8_t msg[MBX_MSG_MAX];

void setUp(void)
{
	memset(msg, 0, sizeof msg);
}

void tearDown(void) {}

static mbx_hdr cmd_hdr(uint16_t code)
{
	return (mbx_hdr){ .magic = MBX_MAGIC,
			  .version = MBX_VERSION,
			  .kind = MBX_KIND_COMMAND,
			  .code = code,
			  .line = 1,
			  .client = 0x00010002,
			  .corr = 0x1122334455667788ull,
			  .token = 0xA1A2A3A4A5A6A7A8ull };
}

/* Build, decode and validate a command; returns the status, *bad the
 * reason. */
static int check(const mbx_hdr *h, const void *payload, size_t len, mbx_bad *bad)
{
	mbx_hdr d;
	int n = mbx_msg_build(msg, sizeof msg, h, payload, len);

	TEST_ASSERT_TRUE(n > 0);
	int rc = mbx_hdr_decode(msg, (size_t)n, &d, bad);

	if (rc)
		return rc;
	return mbx_cmd_validate(&d, msg + MBX_HDR_SIZE, bad);
}

#define ASSERT_BAD(expect_status, expect_bad, h, p, len)                                        \
	do {                                                                                    \
		mbx_bad b_ = MBX_BAD_NONE;                                                      \
		int rc_ = check(&(h), (p), (len), &b_);                                         \
		TEST_ASSERT_EQUAL_INT_MESSAGE(expect_status, rc_, mbx_bad_to_string(b_));       \
		TEST_ASSERT_EQUAL_STRING(mbx_bad_to_string(expect_bad), mbx_bad_to_string(b_)); \
	} while (0)

#define ASSERT_OK(h, p, len) ASSERT_BAD(0, MBX_BAD_NONE, h, p, len)

/* ---- header ---------------------------------------------------------------- */

static void test_header_encoding_is_little_endian_byte_by_byte(void)
{
	mbx_hdr h = {
		.magic = MBX_MAGIC,
		.version = 1,
		.kind = MBX_KIND_RESPONSE,
		.code = 0x0201,
		.line = 3,
		.flags = MBX_F_CHUNKED | MBX_F_MORE,
		.client = 0x04030201,
		.status = -13,
		.corr = 0x0807060504030201ull,
		.token = 0,
		.abort = 0x06020000,
		.dropped = 0,
		.chunk = 0x0102,
		.len = 0,
		.total = 0x00030201,
	};
	static const uint8_t expect[MBX_HDR_SIZE] = {
		0x43, 0x57, 0x01, 0x02, 0x01, 0x02, 0x03, 0x03, /* 0..7 */
		0x01, 0x02, 0x03, 0x04, 0xF3, 0xFF, 0xFF, 0xFF, /* client, -13 */
		0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, /* corr */
		0,    0,    0,    0,    0,    0,    0,    0,    /* token */
		0x00, 0x00, 0x02, 0x06, 0,    0,    0,    0,    /* abort, dropped */
		0x02, 0x01, 0x00, 0x00, 0x01, 0x02, 0x03, 0x00, /* chunk len total */
	};
	uint8_t buf[MBX_HDR_SIZE];
	mbx_hdr d;

	mbx_hdr_encode(&h, buf);
	TEST_ASSERT_EQUAL_HEX8_ARRAY(expect, buf, MBX_HDR_SIZE);
	TEST_ASSERT_EQUAL_INT(0, mbx_hdr_decode(buf, sizeof buf, &d, NULL));
	TEST_ASSERT_EQUAL_MEMORY(&h, &d, sizeof h);
}

static void test_round_trip_with_payload(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_SDO_UPLOAD), d;
	mbx_sdo_req r = { .node = 5, .index = 0x1018, .sub = 1, .timeout_ms = 500 };
	mbx_sdo_req back;
	int n = mbx_msg_build(msg, sizeof msg, &h, &r, sizeof r);

	TEST_ASSERT_EQUAL_INT(MBX_HDR_SIZE + 16, n);
	TEST_ASSERT_EQUAL_INT(0, mbx_hdr_decode(msg, (size_t)n, &d, NULL));
	TEST_ASSERT_EQUAL_UINT16(16, d.len);
	TEST_ASSERT_EQUAL_UINT64(h.corr, d.corr);
	TEST_ASSERT_EQUAL_UINT64(h.token, d.token);
	TEST_ASSERT_EQUAL_INT(0, mbx_cmd_validate(&d, msg + MBX_HDR_SIZE, NULL));
	memcpy(&back, msg + MBX_HDR_SIZE, sizeof back);
	TEST_ASSERT_EQUAL_UINT8(5, back.node);
	TEST_ASSERT_EQUAL_UINT16(0x1018, back.index);
	TEST_ASSERT_EQUAL_UINT32(500, back.timeout_ms);
	/* wire bytes of the payload: node, mode, index LE, sub */
	TEST_ASSERT_EQUAL_HEX8(0x05, msg[48]);
	TEST_ASSERT_EQUAL_HEX8(0x18, msg[50]);
	TEST_ASSERT_EQUAL_HEX8(0x10, msg[51]);
	TEST_ASSERT_EQUAL_HEX8(0x01, msg[52]);
	TEST_ASSERT_EQUAL_HEX8(0xF4, msg[56]);
	TEST_ASSERT_EQUAL_HEX8(0x01, msg[57]);
}

static void test_msg_build_refuses_overflow(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_OD_WRITE);
	uint8_t small[60];

	TEST_ASSERT_EQUAL_INT(-EMSGSIZE, mbx_msg_build(small, sizeof small, &h, msg, 13));
	TEST_ASSERT_EQUAL_INT(-EMSGSIZE, mbx_msg_build(msg, sizeof msg, &h, msg, 70000));
}

static void test_bad_short_message(void)
{
	mbx_hdr d;
	mbx_bad b;

	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_hdr_decode(msg, MBX_HDR_SIZE - 1, &d, &b));
	TEST_ASSERT_EQUAL_INT(MBX_BAD_SHORT, b);
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_hdr_decode(msg, 0, &d, &b));
}

static void test_bad_magic(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_PING);

	h.magic = 0x4357; /* byte-swapped */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_MAGIC, h, NULL, 0);
}

static void test_bad_version(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_PING);

	h.version = 2;
	ASSERT_BAD(MBX_E_VERSION, MBX_BAD_VERSION, h, NULL, 0);
	h.version = 0;
	ASSERT_BAD(MBX_E_VERSION, MBX_BAD_VERSION, h, NULL, 0);
}

static void test_bad_kind(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_PING);

	h.kind = 0;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_KIND, h, NULL, 0);
	h.kind = 4;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_KIND, h, NULL, 0);
}

static void test_bad_len_field(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_PING), d;
	mbx_bad b;

	mbx_msg_build(msg, sizeof msg, &h, NULL, 0);
	msg[42] = 4; /* claims 4 payload bytes, none follow */
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_hdr_decode(msg, MBX_HDR_SIZE, &d, &b));
	TEST_ASSERT_EQUAL_INT(MBX_BAD_LEN, b);
	msg[42] = 0; /* claims none, 4 follow */
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_hdr_decode(msg, MBX_HDR_SIZE + 4, &d, &b));
	TEST_ASSERT_EQUAL_INT(MBX_BAD_LEN, b);
}

static void test_bad_flags(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_PING);

	h.flags = 0x80;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_FLAGS, h, NULL, 0);
	h.flags = MBX_F_OVERFLOW; /* only the daemon sets it */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_FLAGS, h, NULL, 0);
	h.flags = MBX_F_MORE; /* without CHUNKED */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_FLAGS, h, NULL, 0);
	h.flags = MBX_F_NO_REPLY;
	ASSERT_OK(h, NULL, 0);
}

static void test_bad_status_abort_dropped_in_command(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_PING);

	h.status = -1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, NULL, 0);
	h = cmd_hdr(MBX_CMD_PING);
	h.abort = 0x06020000;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, NULL, 0);
	h = cmd_hdr(MBX_CMD_PING);
	h.dropped = 1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, NULL, 0);
}

static void test_bad_token_or_dropped_in_response(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_PING), d;
	mbx_bad b;
	int n;

	h.kind = MBX_KIND_RESPONSE; /* token still set */
	n = mbx_msg_build(msg, sizeof msg, &h, NULL, 0);
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_hdr_decode(msg, (size_t)n, &d, &b));
	TEST_ASSERT_EQUAL_INT(MBX_BAD_RESERVED, b);
	h.token = 0;
	h.dropped = 3; /* without OVERFLOW */
	n = mbx_msg_build(msg, sizeof msg, &h, NULL, 0);
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_hdr_decode(msg, (size_t)n, &d, &b));
	TEST_ASSERT_EQUAL_INT(MBX_BAD_RESERVED, b);
	h.flags = MBX_F_OVERFLOW;
	n = mbx_msg_build(msg, sizeof msg, &h, NULL, 0);
	TEST_ASSERT_EQUAL_INT(0, mbx_hdr_decode(msg, (size_t)n, &d, &b));
	TEST_ASSERT_EQUAL_UINT32(3, d.dropped);
	h.flags = MBX_F_NO_REPLY; /* a command flag */
	n = mbx_msg_build(msg, sizeof msg, &h, NULL, 0);
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_hdr_decode(msg, (size_t)n, &d, &b));
	TEST_ASSERT_EQUAL_INT(MBX_BAD_FLAGS, b);
}

static void test_bad_chunk_and_total_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_PING);

	h.chunk = 1; /* not chunked */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_CHUNK, h, NULL, 0);
	h = cmd_hdr(MBX_CMD_PING);
	h.total = 10; /* not chunked */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_CHUNK, h, NULL, 0);
	h = cmd_hdr(MBX_CMD_OD_WRITE);
	h.flags = MBX_F_CHUNKED | MBX_F_MORE; /* total 0 */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_CHUNK, h, msg, 8);
}

/* The manager's commands: node ranges, 1F82h values, reserved bytes. */
static void test_manager_commands(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_MGR_REQUEST_NMT);
	mbx_mgr_nmt_req r = { .node = 128, .cmd = 5 };
	mbx_mgr_node_req n = { .node = 0 };

	TEST_ASSERT_NOT_NULL(mbx_cmd_lookup(MBX_CMD_MGR_STATUS));
	TEST_ASSERT_TRUE(mbx_cmd_lookup(MBX_CMD_MGR_BOOT)->flags & MBX_CI_WRITE);
	TEST_ASSERT_FALSE(mbx_cmd_lookup(MBX_CMD_MGR_NODE_DIAG)->flags & MBX_CI_WRITE);
	r.cmd = 9;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.cmd = 5;
	r.node = 0;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.node = 3;
	r.pad = 1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &r, sizeof r);
	h = cmd_hdr(MBX_CMD_MGR_NODE_DIAG);
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &n, sizeof n); /* node 0 */
	n.node = 128;
	h = cmd_hdr(MBX_CMD_MGR_BOOT);
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &n, sizeof n);

	/* a manual program update: node range, an image of at least one byte,
	 * the per-frame SDO timeout, reserved bytes */
	uint8_t prog[sizeof(mbx_mgr_program_req) + 4] = { 0 };
	mbx_mgr_program_req pr = { .node = 5, .expected = 0x3C2A91F0u, .sdo_timeout_ms = 500 };
	h = cmd_hdr(MBX_CMD_MGR_PROGRAM);
	TEST_ASSERT_TRUE(mbx_cmd_lookup(MBX_CMD_MGR_PROGRAM)->flags & MBX_CI_WRITE);
	memcpy(prog, &pr, sizeof pr);
	ASSERT_OK(h, prog, sizeof prog);
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, prog, sizeof pr); /* no image */
	pr.node = 0;
	memcpy(prog, &pr, sizeof pr);
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, prog, sizeof prog);
	pr.node = 128;
	memcpy(prog, &pr, sizeof pr);
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, prog, sizeof prog);
	pr.node = 5;
	pr.sdo_timeout_ms = MBX_PROGRAM_SDO_TIMEOUT_MAX + 1;
	memcpy(prog, &pr, sizeof pr);
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, prog, sizeof prog);
	pr.sdo_timeout_ms = 0;
	pr.pad[1] = 1;
	memcpy(prog, &pr, sizeof pr);
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, prog, sizeof prog);
	pr.pad[1] = 0;
	memcpy(prog, &pr, sizeof pr);
	h.flags = MBX_F_CHUNKED | MBX_F_MORE; /* a large image: chunked */
	h.total = 65536;
	ASSERT_OK(h, prog, sizeof prog);

	TEST_ASSERT_EQUAL_UINT32(MBX_EVC_BOOT, mbx_event_class_of(MBX_EV_MGR_BOOT));
	TEST_ASSERT_EQUAL_UINT32(MBX_EVC_MANAGER, mbx_event_class_of(MBX_EV_MGR_STATE));
	TEST_ASSERT_EQUAL_STRING("manager", mbx_event_class_to_string(MBX_EVC_MANAGER));
}

/* MGR_NODE_SET (docs/mailbox.md "Nodes at run time"): what the mailbox
 * sees in the fixed part is refused there, the rest is the line's. */
static void test_node_set_fields(void)
{
	uint8_t buf[sizeof(mbx_mgr_node_set_req) + 8] = { 0 };
	mbx_mgr_node_set_req r = { .node = 5, .op = MBX_NODE_ADD, .assignment = 0x05 };
	mbx_hdr h = cmd_hdr(MBX_CMD_MGR_NODE_SET);
	const mbx_mgr_node_set_req ok = r;

	TEST_ASSERT_TRUE(mbx_cmd_lookup(MBX_CMD_MGR_NODE_SET)->flags & MBX_CI_WRITE);
	TEST_ASSERT_EQUAL_STRING("manager-node-set", mbx_cmd_to_string(MBX_CMD_MGR_NODE_SET));
	ASSERT_OK(h, &r, sizeof r);
	memcpy(buf, &r, sizeof r); /* with a concise DCF */
	ASSERT_OK(h, buf, sizeof buf);
#define BAD_FIELD(field, value, status, why)              \
	do {                                              \
		r = ok;                                   \
		r.field = value;                          \
		ASSERT_BAD(status, why, h, &r, sizeof r); \
	} while (0)
	BAD_FIELD(node, 0, MBX_E_PARAM, MBX_BAD_PARAM);
	BAD_FIELD(node, 128, MBX_E_PARAM, MBX_BAD_PARAM);
	BAD_FIELD(op, 0, MBX_E_PARAM, MBX_BAD_PARAM);
	BAD_FIELD(op, 4, MBX_E_PARAM, MBX_BAD_PARAM);
	BAD_FIELD(flags, 0x04, MBX_E_PARAM, MBX_BAD_PARAM);
	BAD_FIELD(pdo, 3, MBX_E_PARAM, MBX_BAD_PARAM);
	BAD_FIELD(target_state, 1, MBX_E_PARAM, MBX_BAD_PARAM);
	BAD_FIELD(assignment, 0x04, MBX_E_PARAM, MBX_BAD_PARAM); /* not a slave */
	BAD_FIELD(pad, 1, MBX_E_MALFORMED, MBX_BAD_RESERVED);
	r = ok; /* a heartbeat and a guard time */
	r.heartbeat_ms = 500;
	r.assignment |= 100u << 16;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
#undef BAD_FIELD
	/* remove: the other fields are not read, but no data */
	r = (mbx_mgr_node_set_req){ .node = 5, .op = MBX_NODE_REMOVE };
	ASSERT_OK(h, &r, sizeof r);
	memcpy(buf, &r, sizeof r);
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, buf, sizeof buf);
	r.target_state = 127;
	r.flags = 0x80;
	ASSERT_OK(h, &r, sizeof r);
}

static void test_bad_command_code(void)
{
	mbx_hdr h = cmd_hdr(0x0A7F); /* manager family: no such command */

	ASSERT_BAD(MBX_E_UNKNOWN_CMD, MBX_BAD_CMD, h, NULL, 0);
	h.code = 0;
	ASSERT_BAD(MBX_E_UNKNOWN_CMD, MBX_BAD_CMD, h, NULL, 0);
	h.code = 0xFFFF;
	ASSERT_BAD(MBX_E_UNKNOWN_CMD, MBX_BAD_CMD, h, NULL, 0);
}

/* ---- chunking rules -------------------------------------------------------------- */

static void test_chunking_rules(void)
{
	mbx_obj_req o = { .index = 0x2000 };
	uint8_t p[40] = { 0 };
	mbx_hdr h = cmd_hdr(MBX_CMD_OD_WRITE);

	memcpy(p, &o, sizeof o);
	h.flags = MBX_F_CHUNKED | MBX_F_MORE;
	h.total = 100;
	ASSERT_OK(h, p, 40); /* first chunk: 4 fixed + 36 data of 100 */
	h.total = 36;        /* everything in the first: must not chunk */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_CHUNK, h, p, 40);
	h.total = 100;
	h.flags = MBX_F_CHUNKED; /* first and last at once */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_CHUNK, h, p, 40);
	h.flags = MBX_F_CHUNKED | MBX_F_MORE;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_CHUNK, h, p, 3); /* < fixed */
	h.chunk = 1; /* continuation: data only, not empty */
	ASSERT_OK(h, p, 3);
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, p, 0);
	/* only uncapped data commands may be chunked */
	h = cmd_hdr(MBX_CMD_NMT);
	h.flags = MBX_F_CHUNKED | MBX_F_MORE;
	h.total = 100;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_CHUNK, h, p, 4);
	h.code = MBX_CMD_PDO_WRITE;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_CHUNK, h, p, 8);
}

/* ---- payloads -------------------------------------------------------------------- */

static void test_payload_sizes_per_command(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_PING);
	uint8_t z[64] = { 0 };

	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, z, 1);
	h.code = MBX_CMD_NMT;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, z, 3);
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, z, 5);
	h.code = MBX_CMD_SDO_UPLOAD;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, z, 15);
	h.code = MBX_CMD_OD_WRITE;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, z, 3);
	ASSERT_OK(h, z, 4); /* empty value: allowed (empty string) */
	h.code = MBX_CMD_LSS_STORE;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, z, 0);
	h.code = MBX_CMD_LINE_STATUS;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, z, 4);
	h.code = MBX_CMD_REGISTER;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, z, 12);
}

static mbx_register_req good_register(void)
{
	mbx_register_req r;

	memset(&r, 0, sizeof r);
	r.pid = 1234;
	r.uid = 1000;
	strcpy(r.resp_queue, "/cogw.main.c1234.1.resp");
	strcpy(r.event_queue, "/cogw.main.c1234.1.evt");
	return r;
}

static void test_register_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_REGISTER);
	mbx_register_req r = good_register();

	ASSERT_OK(h, &r, sizeof r);
	r.pid = 0;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r = good_register();
	r.reserved = 1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &r, sizeof r);
	r = good_register();
	r.resp_queue[0] = 'x'; /* no leading slash */
	ASSERT_BAD(MBX_E_QUEUE, MBX_BAD_QUEUE, h, &r, sizeof r);
	r = good_register();
	memset(r.event_queue + 1, 'a', MBX_QNAME_MAX - 1); /* no NUL */
	ASSERT_BAD(MBX_E_QUEUE, MBX_BAD_QUEUE, h, &r, sizeof r);
	r = good_register();
	strcpy(r.event_queue, "/a/b"); /* second slash */
	ASSERT_BAD(MBX_E_QUEUE, MBX_BAD_QUEUE, h, &r, sizeof r);
	r = good_register();
	strcpy(r.event_queue, r.resp_queue); /* one queue for both */
	ASSERT_BAD(MBX_E_QUEUE, MBX_BAD_QUEUE, h, &r, sizeof r);
	r = good_register();
	strcpy(r.resp_queue, "/"); /* empty name */
	ASSERT_BAD(MBX_E_QUEUE, MBX_BAD_QUEUE, h, &r, sizeof r);
	/* the two queues of one client, named as a pair: no command queue
	 * of any line, no swapped or mixed queues */
	static const char *const not_pairs[][2] = {
		{ "/cogw.main.line1.cmd", "/cogw.main.line0.cmd" },
		{ "/cogw.main.line1.cmd", "/cogw.main.c1234.1.evt" },
		{ "/cogw.main.c1234.1.evt", "/cogw.main.c1234.1.resp" },
		{ "/cogw.main.c1234.1.resp", "/cogw.main.c1234.2.evt" },
		{ "/cogw.main.c1234.1.resp", "/cogw.main.c1234.1.resp.evt" },
		{ "/.resp", "/.evt" },
		{ "/x.resp", "/x.evtx" },
	};
	for (size_t i = 0; i < sizeof not_pairs / sizeof not_pairs[0]; i++) {
		r = good_register();
		strcpy(r.resp_queue, not_pairs[i][0]);
		strcpy(r.event_queue, not_pairs[i][1]);
		ASSERT_BAD(MBX_E_QUEUE, MBX_BAD_QUEUE, h, &r, sizeof r);
	}
	r = good_register();
	strcpy(r.resp_queue, "/x.resp"); /* the shortest pair */
	strcpy(r.event_queue, "/x.evt");
	ASSERT_OK(h, &r, sizeof r);
}

static void test_subscribe_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_SUBSCRIBE);
	mbx_subscribe_req r = { .classes = MBX_EVC_HB | MBX_EVC_RAW,
				.n_filters = 1,
				.filters = { { 0x181, 0x7FF } } };

	ASSERT_OK(h, &r, sizeof r);
	r.classes = 1u << 20; /* unknown class */
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.classes = MBX_EVC_RAW;
	r.n_filters = 5;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.n_filters = 1;
	r.classes = MBX_EVC_HB; /* filters without raw */
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.classes = MBX_EVC_RAW;
	r.filters[2].mask = 1; /* unused filter slot not zero */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &r, sizeof r);
	r.filters[2].mask = 0;
	r.pad[1] = 1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &r, sizeof r);

	mbx_unsubscribe_req u = { .classes = MBX_EVC_ALL };

	h.code = MBX_CMD_UNSUBSCRIBE;
	ASSERT_OK(h, &u, sizeof u);
	u.classes = (MBX_EVC_ALL + 1) & ~MBX_EVC_ALL; /* the first unknown class bit */
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &u, sizeof u);
}

static void test_xfer_ack_and_object_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_XFER_ACK);
	mbx_xfer_ack a = { .next_chunk = 4, .pad = 1 };
	mbx_obj_req o = { .index = 0x2000, .sub = 1, .flags = 1 };
	uint8_t p[16] = { 0 };

	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &a, sizeof a);
	h.code = MBX_CMD_OD_READ;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &o, sizeof o);
	h.code = MBX_CMD_PDO_WRITE; /* trigger flag allowed here */
	memcpy(p, &o, sizeof o);
	ASSERT_OK(h, p, 6);
	p[3] = 0x02;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, p, 6);
	p[3] = 0;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, p, 4);  /* no data */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, p, 13); /* 9 data */
}

static void test_sdo_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_SDO_UPLOAD);
	mbx_sdo_req r = { .node = 1, .index = 0x1000 };

	ASSERT_OK(h, &r, sizeof r);
	r.node = 127;
	ASSERT_OK(h, &r, sizeof r);
	r.node = 0;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.node = 128;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.node = 5;
	r.mode = 4;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.mode = 3;
	r.pad[2] = 9;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &r, sizeof r);
	r.pad[2] = 0;
	r.size = 100; /* a hint for an upload, meaningless for a download */
	ASSERT_OK(h, &r, sizeof r);
	h.code = MBX_CMD_SDO_DOWNLOAD;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &r, sizeof r);
}

static void test_nmt_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_NMT);
	static const uint8_t good[] = { 0x01, 0x02, 0x80, 0x81, 0x82 };
	mbx_nmt_req r = { 0 };

	for (unsigned i = 0; i < sizeof good; i++) {
		r.cs = good[i];
		ASSERT_OK(h, &r, sizeof r);
	}
	r.cs = 0x03;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.cs = 0x01;
	r.node = 128;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.node = 127;
	r.pad = 1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &r, sizeof r);
}

/* The application watchdog, the hold and host ready: bounds, one NMT
 * reaction at most, flags 0/1, zero padding; the reaction names both ways. */
static void test_app_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_APP_WATCHDOG);
	mbx_appwd_req w = { .interval_ms = 200,
			    .reactions = MBX_APPWD_R_EMCY | MBX_APPWD_R_NMT_STOP };
	mbx_appwd_hold_req f = { .hold = 1 };
	uint32_t set = 0;
	char text[160];

	ASSERT_OK(h, &w, sizeof w);
	w.reactions = MBX_APPWD_R_CONFIGURED;
	ASSERT_OK(h, &w, sizeof w);
	w = (mbx_appwd_req){ 0 }; /* withdrawal */
	ASSERT_OK(h, &w, sizeof w);
	w.reactions = MBX_APPWD_R_EMCY;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &w, sizeof w);
	w.interval_ms = MBX_APPWD_INTERVAL_MIN_MS - 1;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &w, sizeof w);
	w.interval_ms = MBX_APPWD_INTERVAL_MAX_MS + 1;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &w, sizeof w);
	w.interval_ms = 100;
	w.reactions = MBX_APPWD_R_NMT_STOP | MBX_APPWD_R_NMT_PREOP;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &w, sizeof w);
	w.reactions = 1u << 7;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &w, sizeof w);
	w.reactions = MBX_APPWD_R_CONFIGURED | MBX_APPWD_R_EMCY;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &w, sizeof w);

	h = cmd_hdr(MBX_CMD_APP_HOLD);
	ASSERT_OK(h, &f, sizeof f);
	f.hold = 2;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &f, sizeof f);
	f.hold = 0;
	f.pad[1] = 1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &f, sizeof f);
	h = cmd_hdr(MBX_CMD_HOST_READY);
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &f, sizeof f);
	TEST_ASSERT_TRUE(mbx_cmd_lookup(MBX_CMD_APP_KEEPALIVE)->flags & MBX_CI_WRITE);
	TEST_ASSERT_FALSE(mbx_cmd_lookup(MBX_CMD_APP_STATUS)->flags & MBX_CI_WRITE);

	TEST_ASSERT_EQUAL_STRING("safe-outputs",
				 mbx_appwd_reaction_to_string(MBX_APPWD_R_SAFE_OUTPUTS));
	TEST_ASSERT_EQUAL_STRING("?", mbx_appwd_reaction_to_string(3));
	mbx_appwd_reactions_format(MBX_APPWD_R_ALL, text, sizeof text);
	TEST_ASSERT_EQUAL_STRING("emcy,nmt-preop,nmt-stop,nmt-reset-comm,nmt-reset-node,hb-stop,"
				 "safe-outputs",
				 text);
	TEST_ASSERT_EQUAL_INT(0, mbx_appwd_reactions_parse(text, &set));
	TEST_ASSERT_EQUAL_HEX32(MBX_APPWD_R_ALL, set);
	mbx_appwd_reactions_format(0, text, sizeof text);
	TEST_ASSERT_EQUAL_STRING("none", text);
	TEST_ASSERT_EQUAL_INT(
		12, mbx_appwd_reactions_format(MBX_APPWD_R_EMCY | MBX_APPWD_R_HB_STOP, text, 4));
	TEST_ASSERT_EQUAL_STRING("emc", text);
	TEST_ASSERT_EQUAL_INT(-1, mbx_appwd_reactions_parse("emcy,,hb-stop", &set));
	TEST_ASSERT_EQUAL_INT(-1, mbx_appwd_reactions_parse("emcy,bang", &set));
	TEST_ASSERT_EQUAL_INT(-1, mbx_appwd_reactions_parse("", &set));
	TEST_ASSERT_EQUAL_STRING("app", mbx_event_class_to_string(MBX_EVC_APP));
	TEST_ASSERT_EQUAL_STRING("app-watchdog-timeout",
				 mbx_event_to_string(MBX_EV_APP_WD_TIMEOUT));
}

static void test_pdo_request_and_store_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_PDO_REQUEST);
	mbx_pdo_num_req p = { .pdo = 1 };
	mbx_store_req s = { .sub = 1 };

	ASSERT_OK(h, &p, sizeof p);
	p.pdo = 0;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &p, sizeof p);
	p.pdo = 513;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &p, sizeof p);
	p.pdo = 512;
	p.pad = 1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &p, sizeof p);

	h.code = MBX_CMD_STORE;
	ASSERT_OK(h, &s, sizeof s);
	s.sub = 0;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &s, sizeof s);
	s.sub = 128;
	h.code = MBX_CMD_RESTORE;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &s, sizeof s);
	s.sub = 3;
	s.pad[0] = 1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &s, sizeof s);
}

/* NODE_SCAN: a range inside 1..127, a bounded timeout, pads zero;
 * NODE_SCAN_CACHE takes nothing. */
static void test_node_scan_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_NODE_SCAN);
	mbx_scan_req r = { .first = 1, .last = 127 };

	ASSERT_OK(h, &r, sizeof r);
	r.timeout_ms = MBX_SCAN_TIMEOUT_MAX_MS;
	r.parallel = 128;
	ASSERT_OK(h, &r, sizeof r);
	r.timeout_ms = MBX_SCAN_TIMEOUT_MAX_MS + 1;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.timeout_ms = 50;
	r.parallel = 129;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.parallel = 4;
	r.first = 0;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.first = 10;
	r.last = 9;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.last = 128;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.last = 10;
	r.pad[2] = 1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &r, sizeof r);
	r.pad[2] = 0;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, &r, sizeof r - 1);
	TEST_ASSERT_TRUE(mbx_cmd_lookup(MBX_CMD_NODE_SCAN)->flags & MBX_CI_WRITE);

	h = cmd_hdr(MBX_CMD_NODE_SCAN_CACHE);
	ASSERT_OK(h, NULL, 0);
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, &r, sizeof r);
	TEST_ASSERT_FALSE(mbx_cmd_lookup(MBX_CMD_NODE_SCAN_CACHE)->flags & MBX_CI_WRITE);
	/* the event: its class and size */
	TEST_ASSERT_EQUAL_UINT32(MBX_EVC_MANAGER, mbx_event_class_of(MBX_EV_UNKNOWN_NODE));
	TEST_ASSERT_EQUAL_STRING("unknown-node", mbx_event_to_string(MBX_EV_UNKNOWN_NODE));
	TEST_ASSERT_EQUAL_STRING("boot", mbx_unknown_policy_to_string(MBX_UNKNOWN_BOOT));
	TEST_ASSERT_EQUAL_STRING("no-match", mbx_unknown_action_to_string(MBX_UNKNOWN_NO_MATCH));
	TEST_ASSERT_EQUAL_STRING("?", mbx_unknown_action_to_string(6));
	TEST_ASSERT_EQUAL_STRING("emcy", mbx_ident_source_to_string(MBX_IDENT_EMCY));
}

static void test_raw_send_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_RAW_SEND);
	mbx_raw_frame f[33];

	memset(f, 0, sizeof f);
	f[0] = (mbx_raw_frame){ .id = 0x7FF, .len = 2, .data = { 1, 2 } };
	f[1] = (mbx_raw_frame){ .id = 0x1ABCDEF0u | MBX_RAW_EXT, .len = 3 };
	ASSERT_OK(h, f, 2 * sizeof f[0]);
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, f, 0);
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, f, 33 * sizeof f[0]);
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, f, 20); /* not n*16 */
	f[0].id = 0x800;                                     /* 12 bits without EXT */
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, f, sizeof f[0]);
	f[0].id = 0x20000000u | MBX_RAW_EXT; /* 30 bits */
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, f, sizeof f[0]);
	f[0].id = 0x100;
	f[0].len = 9;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, f, sizeof f[0]);
	f[0].len = 1; /* data[1] = 2 beyond len */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, f, sizeof f[0]);
	f[0].len = 2;
	f[0].pad[0] = 1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, f, sizeof f[0]);
}

static void test_lss_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_LSS_SWITCH_GLOBAL);
	mbx_lss_req r = { .mode = 1 };

	ASSERT_OK(h, &r, sizeof r);
	r.mode = 2;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r = (mbx_lss_req){ .node = 255 };
	h.code = MBX_CMD_LSS_SET_NODE_ID;
	ASSERT_OK(h, &r, sizeof r);
	r.node = 0;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.node = 128;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r = (mbx_lss_req){ .what = 0x5E };
	h.code = MBX_CMD_LSS_INQUIRE;
	ASSERT_OK(h, &r, sizeof r);
	r.what = 0x59;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r = (mbx_lss_req){ .rev_lo = 5, .rev_hi = 4 };
	h.code = MBX_CMD_LSS_IDENTIFY_REMOTE;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r = (mbx_lss_req){ .pad = 1 };
	h.code = MBX_CMD_LSS_STORE;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &r, sizeof r);
}

/* ---- names, queue names, filters, events, limits ---------------------------------- */

static void test_names(void)
{
	TEST_ASSERT_EQUAL_STRING("sdo-upload", mbx_cmd_to_string(0x0201));
	TEST_ASSERT_EQUAL_STRING("register", mbx_cmd_to_string(0x0001));
	TEST_ASSERT_EQUAL_STRING("restore", mbx_cmd_to_string(0x0902));
	TEST_ASSERT_EQUAL_STRING("?", mbx_cmd_to_string(0x0A00));
	TEST_ASSERT_EQUAL_STRING("access denied", mbx_status_to_string(MBX_E_ACCESS));
	TEST_ASSERT_EQUAL_STRING("unknown status", mbx_status_to_string(-99));
	TEST_ASSERT_EQUAL_STRING("hb", mbx_event_class_to_string(MBX_EVC_HB));
	TEST_ASSERT_EQUAL_STRING("?", mbx_event_class_to_string(3));
	TEST_ASSERT_EQUAL_STRING("hb-lost", mbx_event_to_string(MBX_EV_HB_LOST));
	TEST_ASSERT_EQUAL_UINT32(MBX_EVC_HB, mbx_event_class_of(MBX_EV_HB_LOST));
	TEST_ASSERT_EQUAL_STRING("dup-node", mbx_event_to_string(MBX_EV_DUP_NODE));
	TEST_ASSERT_EQUAL_UINT32(MBX_EVC_NMT, mbx_event_class_of(MBX_EV_DUP_NODE));
	TEST_ASSERT_EQUAL_UINT32(0, mbx_event_class_of(0x7777));
	TEST_ASSERT_EQUAL_STRING("bus-off", mbx_can_state_to_string(3));
	TEST_ASSERT_EQUAL_STRING("write", mbx_access_to_string(2));
	TEST_ASSERT_EQUAL_STRING("event", mbx_kind_to_string(3));
	for (unsigned b = 0; b < MBX_BAD_COUNT; b++)
		TEST_ASSERT_NOT_EQUAL(0, strcmp("?", mbx_bad_to_string(b)));
	/* every command in the table is found and named */
	static const uint16_t codes[] = { 0x0001, 0x0007, 0x0101, 0x0202, 0x0302, 0x0403,
					  0x0501, 0x0601, 0x070A, 0x0801, 0x0901 };
	for (unsigned i = 0; i < sizeof codes / sizeof codes[0]; i++) {
		const mbx_cmd_info *ci = mbx_cmd_lookup(codes[i]);

		TEST_ASSERT_NOT_NULL(ci);
		TEST_ASSERT_EQUAL_UINT16(codes[i], ci->code);
	}
	/* write-type classification drives access control */
	TEST_ASSERT_FALSE(mbx_cmd_lookup(MBX_CMD_SDO_UPLOAD)->flags & MBX_CI_WRITE);
	TEST_ASSERT_TRUE(mbx_cmd_lookup(MBX_CMD_SDO_DOWNLOAD)->flags & MBX_CI_WRITE);
	TEST_ASSERT_TRUE(mbx_cmd_lookup(MBX_CMD_NMT)->flags & MBX_CI_WRITE);
	TEST_ASSERT_FALSE(mbx_cmd_lookup(MBX_CMD_NODE_TABLE)->flags & MBX_CI_WRITE);
}

static void test_queue_names(void)
{
	char b[MBX_QNAME_MAX];

	TEST_ASSERT_EQUAL_INT(0, mbx_queue_name(b, sizeof b, "main", 2));
	TEST_ASSERT_EQUAL_STRING("/cogw.main.line2.cmd", b);
	TEST_ASSERT_EQUAL_INT(-EINVAL, mbx_queue_name(b, sizeof b, "a.b", 0));
	TEST_ASSERT_EQUAL_INT(-EINVAL, mbx_queue_name(b, sizeof b, "", 0));
	TEST_ASSERT_EQUAL_INT(-EINVAL, mbx_queue_name(b, sizeof b, "x/y", 0));
	TEST_ASSERT_EQUAL_INT(-EINVAL, mbx_queue_name(b, sizeof b, "m", 64));
	TEST_ASSERT_EQUAL_INT(-ENAMETOOLONG, mbx_queue_name(b, 10, "main", 0));
	TEST_ASSERT_TRUE(mbx_instance_is_valid("abcdefghijklmnopqrstuvwxyz012345"));
	TEST_ASSERT_FALSE(mbx_instance_is_valid("abcdefghijklmnopqrstuvwxyz0123456"));
	TEST_ASSERT_TRUE(mbx_queue_name_is_valid("/a", 3));
	TEST_ASSERT_FALSE(mbx_queue_name_is_valid("/a", 2)); /* NUL outside */
	TEST_ASSERT_FALSE(mbx_queue_name_is_valid("/..", 4));
	TEST_ASSERT_FALSE(mbx_queue_name_is_valid("/a b", 5));
}

static void test_raw_filter_match(void)
{
	mbx_raw_filter f = { .id = 0x180, .mask = 0x780 | MBX_RAW_EXT };
	mbx_raw_frame fr = { .id = 0x185 };

	TEST_ASSERT_TRUE(mbx_raw_filter_match(&f, &fr));
	fr.id = 0x205;
	TEST_ASSERT_FALSE(mbx_raw_filter_match(&f, &fr));
	fr.id = 0x185 | MBX_RAW_EXT; /* 29-bit frame: EXT bit compared */
	TEST_ASSERT_FALSE(mbx_raw_filter_match(&f, &fr));
	f.mask = 0; /* everything */
	TEST_ASSERT_TRUE(mbx_raw_filter_match(&f, &fr));
}

static void test_event_validation(void)
{
	uint8_t p[64 * 12 + 16] = { 0 };
	mbx_ev_pdo e = { .pdo = 1, .n = 2 };

	TEST_ASSERT_EQUAL_INT(0, mbx_event_validate(MBX_EV_HB_LOST, p, 4));
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_event_validate(MBX_EV_HB_LOST, p, 5));
	TEST_ASSERT_EQUAL_INT(0, mbx_event_validate(MBX_EV_DUP_NODE, p, 12));
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_event_validate(MBX_EV_DUP_NODE, p, 4));
	TEST_ASSERT_EQUAL_INT(0, mbx_event_validate(MBX_EV_RAW, p, 24));
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_event_validate(MBX_EV_EMCY, p, 23));
	TEST_ASSERT_EQUAL_INT(0, mbx_event_validate(MBX_EV_SDO_DONE, p, 24));
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_event_validate(MBX_EV_SDO_DONE, p, 20));
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_event_validate(MBX_EV_SDO_DONE, p, 28));
	memcpy(p, &e, sizeof e);
	TEST_ASSERT_EQUAL_INT(0, mbx_event_validate(MBX_EV_PDO, p, 16 + 24));
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_event_validate(MBX_EV_PDO, p, 16 + 12));
	e.n = 65;
	memcpy(p, &e, sizeof e);
	TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED, mbx_event_validate(MBX_EV_PDO, p, 16 + 65 * 12));
	TEST_ASSERT_EQUAL_INT(MBX_E_UNKNOWN_CMD, mbx_event_validate(0x9999, p, 0));
}

/* The supervision, SYNC, TIME and guarding events: each has a name, a
 * class a client can subscribe to, and exactly one payload size. */
static void test_supervision_sync_time_events(void)
{
	static const struct {
		uint16_t code;
		uint32_t cls;
		const char *name;
		size_t size;
	} t[] = {
		{ MBX_EV_RPDO_FAULT, MBX_EVC_PDO_FAULT, "rpdo-fault", sizeof(mbx_ev_rpdo_fault) },
		{ MBX_EV_RPDO_RECOVERED, MBX_EVC_PDO_FAULT, "rpdo-recovered",
		  sizeof(mbx_ev_rpdo_fault) },
		{ MBX_EV_SYNC, MBX_EVC_SYNC, "sync", sizeof(mbx_ev_sync) },
		{ MBX_EV_TIME, MBX_EVC_TIME, "time", sizeof(mbx_ev_time) },
		{ MBX_EV_GUARD_TOGGLE, MBX_EVC_HB, "guard-toggle", sizeof(mbx_ev_node) },
		{ MBX_EV_LIFE_LOST, MBX_EVC_HB, "life-lost", sizeof(mbx_ev_node) },
		{ MBX_EV_LIFE_RESUMED, MBX_EVC_HB, "life-resumed", sizeof(mbx_ev_node) },
	};
	uint8_t p[64] = { 0 };

	for (size_t i = 0; i < sizeof t / sizeof t[0]; i++) {
		TEST_ASSERT_EQUAL_STRING(t[i].name, mbx_event_to_string(t[i].code));
		TEST_ASSERT_EQUAL_HEX32(t[i].cls, mbx_event_class_of(t[i].code));
		TEST_ASSERT_TRUE(t[i].cls & MBX_EVC_ALL);
		TEST_ASSERT_EQUAL_INT(0, mbx_event_validate(t[i].code, p, t[i].size));
		TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED,
				      mbx_event_validate(t[i].code, p, t[i].size - 1));
		TEST_ASSERT_EQUAL_INT(MBX_E_MALFORMED,
				      mbx_event_validate(t[i].code, p, t[i].size + 1));
	}
	TEST_ASSERT_EQUAL_STRING("pdo-fault", mbx_event_class_to_string(MBX_EVC_PDO_FAULT));
	TEST_ASSERT_EQUAL_STRING("sync", mbx_event_class_to_string(MBX_EVC_SYNC));
	TEST_ASSERT_EQUAL_STRING("time", mbx_event_class_to_string(MBX_EVC_TIME));
	/* RPDO_STATUS: a read without payload */
	mbx_hdr h = cmd_hdr(MBX_CMD_RPDO_STATUS);
	ASSERT_OK(h, p, 0);
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, p, 4);
	TEST_ASSERT_EQUAL_STRING("rpdo-status", mbx_cmd_to_string(MBX_CMD_RPDO_STATUS));
}

/* Every fault of a line's bus health has its name (cogwctl health, the
 * MQTT topic health/<fault>): a missing one printed "(null)". */
static void test_every_fault_has_a_name(void)
{
	static const char *const expected[MBX_FAULT_COUNT] = {
		"id-collision", "warning", "passive",     "bus-off",
		"rx-overrun",   "tx-lost", "tx-pressure", "link-down",
	};

	for (unsigned f = 0; f < MBX_FAULT_COUNT; f++)
		TEST_ASSERT_EQUAL_STRING(expected[f], mbx_fault_to_string(f));
	TEST_ASSERT_EQUAL_STRING("?", mbx_fault_to_string(MBX_FAULT_COUNT));
}

static void test_system_limits_message(void)
{
	char err[256];
	int rc;

	rc = mbx_check_system_limits(100000, 1024, err, sizeof err);
	TEST_ASSERT_EQUAL_INT(-ERANGE, rc);
	TEST_ASSERT_NOT_NULL(strstr(err, "fs.mqueue.msg_max"));
	TEST_ASSERT_NOT_NULL(strstr(err, "sysctl -w fs.mqueue.msg_max=100000"));
	rc = mbx_check_system_limits(1, 65535, err, sizeof err);
	if (rc) { /* msgsize_max defaults to 8192 */
		TEST_ASSERT_EQUAL_INT(-ERANGE, rc);
		TEST_ASSERT_NOT_NULL(strstr(err, "fs.mqueue.msgsize_max"));
	}
	TEST_ASSERT_EQUAL_INT(-EINVAL, mbx_check_system_limits(0, 1024, err, sizeof err));
	TEST_ASSERT_EQUAL_INT(-EINVAL, mbx_check_system_limits(8, 100, err, sizeof err));
	TEST_ASSERT_EQUAL_INT(0, mbx_check_system_limits(1, 256, err, sizeof err));
	TEST_ASSERT_EQUAL_STRING("", err);
}

static void test_gateway_sdo_fields(void)
{
	mbx_hdr h = cmd_hdr(MBX_CMD_GW_SDO_UPLOAD);
	mbx_gw_sdo_req r = { .net = 2, .sdo = { .node = 5, .index = 0x1000 } };

	TEST_ASSERT_EQUAL_STRING("gw-sdo-upload", mbx_cmd_to_string(MBX_CMD_GW_SDO_UPLOAD));
	TEST_ASSERT_EQUAL_STRING("gw-routes", mbx_cmd_to_string(MBX_CMD_GW_ROUTES));
	ASSERT_OK(h, &r, sizeof r);
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_SIZE, h, &r, sizeof r - 1);
	r.net = 0;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.net = 128;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.net = 127;
	r.sdo.node = 0;
	ASSERT_BAD(MBX_E_PARAM, MBX_BAD_PARAM, h, &r, sizeof r);
	r.sdo.node = 5;
	r.pad = 1;
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &r, sizeof r);
	r.pad = 0;
	h = cmd_hdr(MBX_CMD_GW_SDO_DOWNLOAD);
	r.sdo.size = 4; /* a download's size is its data */
	ASSERT_BAD(MBX_E_MALFORMED, MBX_BAD_RESERVED, h, &r, sizeof r);
	h = cmd_hdr(MBX_CMD_GW_ROUTES);
	ASSERT_OK(h, NULL, 0);
	TEST_ASSERT_TRUE(mbx_cmd_lookup(MBX_CMD_GW_SDO_DOWNLOAD)->flags & MBX_CI_WRITE);
	TEST_ASSERT_FALSE(mbx_cmd_lookup(MBX_CMD_GW_SDO_UPLOAD)->flags & MBX_CI_WRITE);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_header_encoding_is_little_endian_byte_by_byte);
	RUN_TEST(test_round_trip_with_payload);
	RUN_TEST(test_msg_build_refuses_overflow);
	RUN_TEST(test_bad_short_message);
	RUN_TEST(test_bad_magic);
	RUN_TEST(test_bad_version);
	RUN_TEST(test_bad_kind);
	RUN_TEST(test_bad_len_field);
	RUN_TEST(test_bad_flags);
	RUN_TEST(test_bad_status_abort_dropped_in_command);
	RUN_TEST(test_bad_token_or_dropped_in_response);
	RUN_TEST(test_bad_chunk_and_total_fields);
	RUN_TEST(test_node_set_fields);
	RUN_TEST(test_bad_command_code);
	RUN_TEST(test_manager_commands);
	RUN_TEST(test_chunking_rules);
	RUN_TEST(test_payload_sizes_per_command);
	RUN_TEST(test_register_fields);
	RUN_TEST(test_subscribe_fields);
	RUN_TEST(test_xfer_ack_and_object_fields);
	RUN_TEST(test_sdo_fields);
	RUN_TEST(test_gateway_sdo_fields);
	RUN_TEST(test_nmt_fields);
	RUN_TEST(test_app_fields);
	RUN_TEST(test_pdo_request_and_store_fields);
	RUN_TEST(test_raw_send_fields);
	RUN_TEST(test_lss_fields);
	RUN_TEST(test_names);
	RUN_TEST(test_queue_names);
	RUN_TEST(test_raw_filter_match);
	RUN_TEST(test_event_validation);
	RUN_TEST(test_supervision_sync_time_events);
	RUN_TEST(test_every_fault_has_a_name);
	RUN_TEST(test_node_scan_fields);
	RUN_TEST(test_system_limits_message);
	return UNITY_END();
}
