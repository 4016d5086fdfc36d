/* SPDX-License-Identifier: MIT */
/*
 * mailbox/proto.c - the wire format: the 48-byte header (encoding,
 * decoding, validation), the table of commands, their names and the
 * validation of their payloads. Its siblings, which call nothing here:
 * proto_names.c (names of the other values, statuses; the status of a
 * refusal comes from there), proto_events.c (the table of events),
 * proto_queues.c (queue names and the system limits).
 *
 * Everything a client sends is untrusted: every header field and every
 * payload field is checked here, with the reason reported so the server can
 * count it (mbx_server_stats.malformed[reason]). Nothing here allocates or
 * keeps state; both the daemon and libcogw link it.
 */
#include "mailbox/proto.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>

/* Pin every payload layout: a change here is a protocol change. */
_Static_assert(sizeof(mbx_dev_obj_req) == 8, "wire layout");
_Static_assert(sizeof(mbx_dev_forward) == 32, "wire layout");
_Static_assert(sizeof(mbx_dev_node_req) == 4, "wire layout");
_Static_assert(sizeof(mbx_dev_watch_req) == 12, "wire layout");
_Static_assert(sizeof(mbx_dev_watch_resp) == 8, "wire layout");
_Static_assert(sizeof(mbx_scan_req) == 8, "wire layout");
_Static_assert(sizeof(mbx_node_ident) == 32, "wire layout");
_Static_assert(sizeof(mbx_scan_resp) == 24, "wire layout");
_Static_assert(sizeof(mbx_ev_unknown_node) == 40, "wire layout");
_Static_assert(sizeof(mbx_dev_read_req) == 12, "wire layout");
_Static_assert(sizeof(mbx_dev_value) == 32, "wire layout");
_Static_assert(sizeof(mbx_dev_write_resp) == 8, "wire layout");
_Static_assert(sizeof(mbx_dev_layout_node) == 32, "wire layout");
_Static_assert(sizeof(mbx_dev_layout_pdo) == 20, "wire layout");
_Static_assert(sizeof(mbx_dev_layout_entry) == 8, "wire layout");
_Static_assert(sizeof(mbx_ev_dev_mirror) == 12, "wire layout");
_Static_assert(sizeof(mbx_register_req) == 140, "wire layout");
_Static_assert(sizeof(mbx_register_resp) == 32, "wire layout");
_Static_assert(sizeof(mbx_raw_filter) == 8, "wire layout");
_Static_assert(sizeof(mbx_subscribe_req) == 40, "wire layout");
_Static_assert(sizeof(mbx_unsubscribe_req) == 4, "wire layout");
_Static_assert(sizeof(mbx_subscribe_resp) == 4, "wire layout");
_Static_assert(sizeof(mbx_ping_resp) == 16, "wire layout");
_Static_assert(sizeof(mbx_xfer_ack) == 4, "wire layout");
_Static_assert(sizeof(mbx_stats_wire) == 136, "wire layout");
_Static_assert(sizeof(mbx_obj_req) == 4, "wire layout");
_Static_assert(sizeof(mbx_sdo_req) == 16, "wire layout");
_Static_assert(sizeof(mbx_nmt_req) == 4, "wire layout");
_Static_assert(sizeof(mbx_node_entry) == 16, "wire layout");
_Static_assert(sizeof(mbx_pdo_num_req) == 4, "wire layout");
_Static_assert(sizeof(mbx_emcy_req) == 8, "wire layout");
_Static_assert(sizeof(mbx_raw_frame) == 16, "wire layout");
_Static_assert(sizeof(mbx_lss_req) == 36, "wire layout");
_Static_assert(sizeof(mbx_lss_resp) == 24, "wire layout");
_Static_assert(sizeof(mbx_line_status) == 64, "wire layout");
_Static_assert(sizeof(mbx_store_req) == 4, "wire layout");
_Static_assert(sizeof(mbx_ev_overflow) == 8, "wire layout");
_Static_assert(sizeof(mbx_ev_od_written) == 8, "wire layout");
_Static_assert(sizeof(mbx_ev_sdo_done) == 24, "wire layout");
_Static_assert(sizeof(mbx_ev_node) == 4, "wire layout");
_Static_assert(sizeof(mbx_ev_dup_node) == 12, "wire layout");
_Static_assert(sizeof(mbx_pdo_value) == 12, "wire layout");
_Static_assert(sizeof(mbx_ev_pdo) == 16, "wire layout");
_Static_assert(sizeof(mbx_ev_emcy) == 24, "wire layout");
_Static_assert(sizeof(mbx_ev_raw) == 24, "wire layout");
_Static_assert(sizeof(mbx_ev_can_state) == 4, "wire layout");
_Static_assert(sizeof(mbx_ev_rpdo_fault) == 24, "wire layout");
_Static_assert(sizeof(mbx_ev_sync) == 16, "wire layout");
_Static_assert(sizeof(mbx_ev_time) == 24, "wire layout");
_Static_assert(sizeof(mbx_rpdo_status) == 56, "wire layout");
_Static_assert(sizeof(mbx_rpdo_fault_entry) == 12, "wire layout");
_Static_assert(sizeof(mbx_gw_sdo_req) == 20, "wire layout");
_Static_assert(sizeof(mbx_mgr_program_req) == 12, "wire layout");
_Static_assert(sizeof(mbx_mgr_program_resp) == 24, "wire layout");
_Static_assert(sizeof(mbx_gw_status) == 160, "wire layout");
_Static_assert(sizeof(mbx_gw_route) == 40, "wire layout");
_Static_assert(sizeof(mbx_ev_gw_sdo) == 16, "wire layout");
_Static_assert(sizeof(mbx_ev_gw_emcy) == 8, "wire layout");
_Static_assert(sizeof(mbx_app_claim_req) == 16, "wire layout");
_Static_assert(sizeof(mbx_app_answer_req) == 8, "wire layout");
_Static_assert(sizeof(mbx_app_ind_req) == 8, "wire layout");
_Static_assert(sizeof(mbx_ev_app_ind) == 28, "wire layout");
_Static_assert(sizeof(mbx_ev_app_written) == 16, "wire layout");
_Static_assert(sizeof(mbx_ev_app_cancel) == 8, "wire layout");
_Static_assert(sizeof(mbx_app_status) == 48, "wire layout");
_Static_assert(sizeof(mbx_app_obj) == 24, "wire layout");
_Static_assert(sizeof(mbx_appwd_req) == 8, "wire layout");
_Static_assert(sizeof(mbx_appwd_resp) == 8, "wire layout");
_Static_assert(sizeof(mbx_appwd_hold_req) == 4, "wire layout");
_Static_assert(sizeof(mbx_appwd_nmt) == 8, "wire layout");
_Static_assert(sizeof(mbx_host_ready_req) == 4, "wire layout");
_Static_assert(sizeof(mbx_appwd_status) == 96, "wire layout");
_Static_assert(sizeof(mbx_appwd_entry) == 32, "wire layout");
_Static_assert(sizeof(mbx_ev_appwd) == 40, "wire layout");
_Static_assert(sizeof(mbx_ev_host) == 16, "wire layout");
_Static_assert(offsetof(mbx_sdo_req, timeout_ms) == 8, "wire layout");
_Static_assert(offsetof(mbx_lss_req, vendor) == 12, "wire layout");
_Static_assert(offsetof(mbx_ev_emcy, msef) == 12, "wire layout");

/* ---- little-endian helpers ---------------------------------------------- */

static void put16(uint8_t *p, uint16_t v)
{
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
}

static void put32(uint8_t *p, uint32_t v)
{
	put16(p, (uint16_t)v);
	put16(p + 2, (uint16_t)(v >> 16));
}

static void put64(uint8_t *p, uint64_t v)
{
	put32(p, (uint32_t)v);
	put32(p + 4, (uint32_t)(v >> 32));
}

static uint16_t get16(const uint8_t *p)
{
	return (uint16_t)(p[0] | (p[1] << 8));
}

static uint32_t get32(const uint8_t *p)
{
	return (uint32_t)get16(p) | ((uint32_t)get16(p + 2) << 16);
}

static uint64_t get64(const uint8_t *p)
{
	return (uint64_t)get32(p) | ((uint64_t)get32(p + 4) << 32);
}

/* ---- header --------------------------------------------------------------- */

void mbx_hdr_encode(const mbx_hdr *h, uint8_t *b)
{
	put16(b + 0, h->magic);
	b[2] = h->version;
	b[3] = h->kind;
	put16(b + 4, h->code);
	b[6] = h->line;
	b[7] = h->flags;
	put32(b + 8, h->client);
	put32(b + 12, (uint32_t)h->status);
	put64(b + 16, h->corr);
	put64(b + 24, h->token);
	put32(b + 32, h->abort);
	put32(b + 36, h->dropped);
	put16(b + 40, h->chunk);
	put16(b + 42, h->len);
	put32(b + 44, h->total);
}

static int refuse(mbx_bad *out, mbx_bad why)
{
	if (out)
		*out = why;
	return mbx_bad_status(why);
}

static void hdr_read(const uint8_t *b, mbx_hdr *h)
{
	h->magic = get16(b + 0);
	h->version = b[2];
	h->kind = b[3];
	h->code = get16(b + 4);
	h->line = b[6];
	h->flags = b[7];
	h->client = get32(b + 8);
	h->status = (int32_t)get32(b + 12);
	h->corr = get64(b + 16);
	h->token = get64(b + 24);
	h->abort = get32(b + 32);
	h->dropped = get32(b + 36);
	h->chunk = get16(b + 40);
	h->len = get16(b + 42);
	h->total = get32(b + 44);
}

/* The flags and the fields one direction leaves zero. */
static mbx_bad hdr_direction_bad(const mbx_hdr *h)
{
	if (h->kind == MBX_KIND_COMMAND) {
		if (h->flags & ~MBX_F_CMD_MASK)
			return MBX_BAD_FLAGS;
		/* Fields only the daemon fills must be zero from a client:
		 * they can gain a meaning in a later version. */
		if (h->status != 0 || h->abort != 0 || h->dropped != 0)
			return MBX_BAD_RESERVED;
		return MBX_BAD_NONE;
	}
	if (h->flags & ~MBX_F_OUT_MASK)
		return MBX_BAD_FLAGS;
	if (h->token != 0)
		return MBX_BAD_RESERVED;
	if (!(h->flags & MBX_F_OVERFLOW) && h->dropped != 0)
		return MBX_BAD_RESERVED;
	return MBX_BAD_NONE;
}

static mbx_bad hdr_chunk_bad(const mbx_hdr *h)
{
	if ((h->flags & MBX_F_MORE) && !(h->flags & MBX_F_CHUNKED))
		return MBX_BAD_FLAGS;
	if (h->flags & MBX_F_CHUNKED)
		return h->total == 0 ? MBX_BAD_CHUNK : MBX_BAD_NONE;
	return h->chunk != 0 || h->total != 0 ? MBX_BAD_CHUNK : MBX_BAD_NONE;
}

int mbx_hdr_decode(const uint8_t *b, size_t n, mbx_hdr *h, mbx_bad *bad)
{
	mbx_bad why;

	if (bad)
		*bad = MBX_BAD_NONE;
	memset(h, 0, sizeof *h);
	if (n < MBX_HDR_SIZE)
		return refuse(bad, MBX_BAD_SHORT);
	hdr_read(b, h);
	if (h->magic != MBX_MAGIC)
		return refuse(bad, MBX_BAD_MAGIC);
	if (h->version != MBX_VERSION)
		return refuse(bad, MBX_BAD_VERSION);
	if (h->kind < MBX_KIND_COMMAND || h->kind > MBX_KIND_EVENT)
		return refuse(bad, MBX_BAD_KIND);
	if ((size_t)h->len != n - MBX_HDR_SIZE)
		return refuse(bad, MBX_BAD_LEN);
	why = hdr_direction_bad(h);
	if (why == MBX_BAD_NONE)
		why = hdr_chunk_bad(h);
	return why == MBX_BAD_NONE ? 0 : refuse(bad, why);
}

void mbx_hdr_set_recipient(uint8_t *b, uint32_t client, uint32_t dropped)
{
	put32(b + 8, client);
	put32(b + 36, dropped);
	if (dropped)
		b[7] |= MBX_F_OVERFLOW;
	else
		b[7] &= (uint8_t)~MBX_F_OVERFLOW;
}

int mbx_msg_build(uint8_t *buf, size_t cap, const mbx_hdr *h, const void *payload,
		  size_t payload_len)
{
	mbx_hdr hh = *h;

	if (payload_len > MBX_MSG_MAX - MBX_HDR_SIZE || cap < MBX_HDR_SIZE + payload_len)
		return -EMSGSIZE;
	hh.len = (uint16_t)payload_len;
	mbx_hdr_encode(&hh, buf);
	if (payload_len)
		memcpy(buf + MBX_HDR_SIZE, payload, payload_len);
	return (int)(MBX_HDR_SIZE + payload_len);
}

/* ---- payload validation ----------------------------------------------------- */

static bool all_zero(const void *p, size_t n)
{
	const uint8_t *b = p;

	for (size_t i = 0; i < n; i++)
		if (b[i])
			return false;
	return true;
}

static bool raw_id_ok(uint32_t id)
{
	uint32_t bare = id & ~(MBX_RAW_EXT | MBX_RAW_RTR);

	if (id & MBX_RAW_EXT)
		return bare <= 0x1FFFFFFFu;
	return bare <= 0x7FFu;
}

static int check_register(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_register_req r;

	(void)code, (void)len;
	memcpy(&r, p, sizeof r);
	if (r.reserved)
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.pid == 0 || r.pid > 0x3FFFFFFFu)
		return refuse(bad, MBX_BAD_PARAM);
	if (!mbx_queue_name_is_valid(r.resp_queue, MBX_QNAME_MAX) ||
	    !mbx_queue_name_is_valid(r.event_queue, MBX_QNAME_MAX) ||
	    !mbx_client_queues_pair(r.resp_queue, r.event_queue))
		return refuse(bad, MBX_BAD_QUEUE);
	return 0;
}

static int check_subscribe(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_subscribe_req r;

	(void)code, (void)len;
	memcpy(&r, p, sizeof r);
	if (!all_zero(r.pad, sizeof r.pad))
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.classes & ~(MBX_EVC_ALL | MBX_EVC_OVERFLOW))
		return refuse(bad, MBX_BAD_PARAM);
	if (r.n_filters > MBX_RAW_FILTERS_MAX)
		return refuse(bad, MBX_BAD_PARAM);
	if (r.n_filters && !(r.classes & MBX_EVC_RAW))
		return refuse(bad, MBX_BAD_PARAM);
	for (unsigned i = r.n_filters; i < MBX_RAW_FILTERS_MAX; i++)
		if (r.filters[i].id || r.filters[i].mask)
			return refuse(bad, MBX_BAD_RESERVED);
	return 0;
}

static int check_lss(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_lss_req r;

	(void)len;
	memcpy(&r, p, sizeof r);
	if (r.pad)
		return refuse(bad, MBX_BAD_RESERVED);
	switch (code) {
	case MBX_CMD_LSS_SWITCH_GLOBAL:
		if (r.mode > 1)
			return refuse(bad, MBX_BAD_PARAM);
		break;
	case MBX_CMD_LSS_SET_NODE_ID:
		if (!((r.node >= 1 && r.node <= 127) || r.node == 255))
			return refuse(bad, MBX_BAD_PARAM);
		break;
	case MBX_CMD_LSS_INQUIRE:
		if (r.what < 0x5A || r.what > 0x5E)
			return refuse(bad, MBX_BAD_PARAM);
		break;
	case MBX_CMD_LSS_IDENTIFY_REMOTE:
		if (r.rev_lo > r.rev_hi || r.ser_lo > r.ser_hi)
			return refuse(bad, MBX_BAD_PARAM);
		break;
	default:
		break;
	}
	return 0;
}

static int check_unsubscribe(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_unsubscribe_req r;

	(void)code, (void)len;
	memcpy(&r, p, sizeof r);
	if (r.classes & ~(MBX_EVC_ALL | MBX_EVC_OVERFLOW))
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

static int check_xfer_ack(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_xfer_ack r;

	(void)code, (void)len;
	memcpy(&r, p, sizeof r);
	return r.pad ? refuse(bad, MBX_BAD_RESERVED) : 0;
}

/* OD and PDO reads and writes: only PDO_WRITE has a flag (trigger). */
static int check_obj_req(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_obj_req r;

	(void)len;
	memcpy(&r, p, sizeof r);
	if (code == MBX_CMD_PDO_WRITE ? (r.flags & ~MBX_PDO_TRIGGER) : r.flags)
		return refuse(bad, MBX_BAD_RESERVED);
	return 0;
}

/* A download's size is its data's: the field is for uploads. */
static int check_sdo_fields(uint16_t code, const mbx_sdo_req *r, mbx_bad *bad)
{
	if (!all_zero(r->pad, sizeof r->pad))
		return refuse(bad, MBX_BAD_RESERVED);
	if (r->node < 1 || r->node > 127 || r->mode > MBX_SDO_MODE_MAX)
		return refuse(bad, MBX_BAD_PARAM);
	if ((code == MBX_CMD_SDO_DOWNLOAD || code == MBX_CMD_GW_SDO_DOWNLOAD) && r->size)
		return refuse(bad, MBX_BAD_RESERVED);
	return 0;
}

static int check_sdo_req(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_sdo_req r;

	(void)len;
	memcpy(&r, p, sizeof r);
	return check_sdo_fields(code, &r, bad);
}

static int check_gw_sdo_req(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_gw_sdo_req r;

	(void)len;
	memcpy(&r, p, sizeof r);
	if (r.pad || !all_zero(r.sdo.pad, sizeof r.sdo.pad))
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.net < 1 || r.net > 127)
		return refuse(bad, MBX_BAD_PARAM);
	return check_sdo_fields(code, &r.sdo, bad);
}

bool mbx_data_type_is_valid(unsigned type)
{
	/* 0Eh and 17h are no basic type (CiA 301 table 44) */
	return type >= MBX_T_BOOLEAN && type <= MBX_T_UNSIGNED64 && type != 0x0E && type != 0x17;
}

/* The fixed part of every DEV_* command that names one object; the watch
 * and read requests begin with it. A co_type is one of CiA 301's basic
 * types (0001h..001Bh) or 0. */
static int check_dev_obj(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_dev_obj_req r;

	(void)code;
	(void)len;
	memcpy(&r, p, sizeof r);
	if (r.flags & ~(unsigned)MBX_DEV_SDO_ONLY)
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.node < 1 || r.node > 127 || (r.type && !mbx_data_type_is_valid(r.type)))
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

/* Application objects live in 2000h..5FFFh and 6000h..9FFFh only: the
 * communication objects and the reserved ranges are the daemon's
 * (docs/application.md). */
static bool app_index_ok(uint16_t index)
{
	return index >= 0x2000 && index <= 0x9FFF;
}

static int check_app_claim(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_app_claim_req r;

	(void)code;
	(void)len;
	memcpy(&r, p, sizeof r);
	if (r.pad || r.pad2 || (r.access & ~MBX_APP_ACCESS_MASK))
		return refuse(bad, MBX_BAD_RESERVED);
	if (!app_index_ok(r.index) || (r.kind != MBX_APP_HELD && r.kind != MBX_APP_SERVED))
		return refuse(bad, MBX_BAD_PARAM);
	if (!r.type) /* a declared object, as declared */
		return r.access || r.max_size ? refuse(bad, MBX_BAD_PARAM) : 0;
	if (!mbx_data_type_is_valid(r.type) || !(r.access & (MBX_APP_READ | MBX_APP_WRITE)) ||
	    r.max_size > MBX_APP_MAX_SIZE)
		return refuse(bad, MBX_BAD_PARAM);
	/* a served value is the owner's: no PDO can wait for it */
	if (r.kind == MBX_APP_SERVED && (r.access & (MBX_APP_RPDO | MBX_APP_TPDO)))
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

static int check_app_answer(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_app_answer_req r;

	(void)code;
	(void)len;
	memcpy(&r, p, sizeof r);
	/* 0xFFFFFFFF is no CiA 301 abort code (core/od.h CO_OD_DEFERRED) */
	if (r.abort == 0xFFFFFFFFu)
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

static int check_app_ind(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_app_ind_req r;

	(void)code;
	(void)len;
	memcpy(&r, p, sizeof r);
	return r.pad ? refuse(bad, MBX_BAD_RESERVED) : 0;
}

static int check_app_release(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_obj_req r;

	(void)code;
	(void)len;
	memcpy(&r, p, sizeof r);
	if (r.flags)
		return refuse(bad, MBX_BAD_RESERVED);
	return app_index_ok(r.index) ? 0 : refuse(bad, MBX_BAD_PARAM);
}

static int check_dev_node(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_dev_node_req r;

	(void)code;
	(void)len;
	memcpy(&r, p, sizeof r);
	if (!all_zero(r.pad, sizeof r.pad))
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.node > 127)
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

/* MGR_BOOT takes node 0 (all nodes), MGR_NODE_DIAG one node. */
static int check_mgr_node_req(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_mgr_node_req r;

	(void)len;
	memcpy(&r, p, sizeof r);
	if (!all_zero(r.pad, sizeof r.pad))
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.node > 127 || (code == MBX_CMD_MGR_NODE_DIAG && r.node < 1))
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

/* The NMT state a node is put in after its boot: 0 (= 5), 4, 5, 127. */
static bool node_target_state_valid(uint8_t state)
{
	return state == 0 || state == 4 || state == 5 || state == 127;
}

static int check_mgr_node_set(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_mgr_node_set_req r;

	(void)code;
	memcpy(&r, p, sizeof r);
	if (r.pad)
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.node < 1 || r.node > 127 || r.op < MBX_NODE_ADD || r.op > MBX_NODE_REMOVE)
		return refuse(bad, MBX_BAD_PARAM);
	if (r.op == MBX_NODE_REMOVE) /* the other fields are not read; no data */
		return len > sizeof r ? refuse(bad, MBX_BAD_PARAM) : 0;
	/* a slave (1F81h bit 0), supervised one way: heartbeat or guarding */
	if ((r.flags & ~MBX_NODE_F_ALL) || r.pdo > 2 || !(r.assignment & 1u) ||
	    !node_target_state_valid(r.target_state) || (r.heartbeat_ms && (r.assignment >> 16)))
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

static int check_mgr_program(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_mgr_program_req r;

	(void)code;
	memcpy(&r, p, sizeof r);
	if (!all_zero(r.pad, sizeof r.pad))
		return refuse(bad, MBX_BAD_RESERVED);
	/* an image of at least one byte (chunked ones always have more) */
	if (r.node < 1 || r.node > 127 || r.sdo_timeout_ms > MBX_PROGRAM_SDO_TIMEOUT_MAX ||
	    len <= sizeof r)
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

/* Request NMT (CiA 302-2): start, stop, pre-operational, reset node or
 * communication; node 128 = all nodes. */
static int check_mgr_request_nmt(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_mgr_nmt_req r;

	(void)code, (void)len;
	memcpy(&r, p, sizeof r);
	if (r.pad)
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.node < 1 || r.node > 128)
		return refuse(bad, MBX_BAD_PARAM);
	switch (r.cmd) {
	case 4:
	case 5:
	case 6:
	case 7:
	case 127:
		return 0;
	}
	return refuse(bad, MBX_BAD_PARAM);
}

/* The NMT command specifiers of CiA 301; node 0 = broadcast. */
static int check_nmt(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_nmt_req r;

	(void)code, (void)len;
	memcpy(&r, p, sizeof r);
	if (r.pad)
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.node > 127)
		return refuse(bad, MBX_BAD_PARAM);
	switch (r.cs) {
	case 0x01:
	case 0x02:
	case 0x80:
	case 0x81:
	case 0x82:
		return 0;
	}
	return refuse(bad, MBX_BAD_PARAM);
}

static int check_pdo_request(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_pdo_num_req r;

	(void)code, (void)len;
	memcpy(&r, p, sizeof r);
	if (r.pad)
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.pdo < 1 || r.pdo > 512)
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

/* Every frame of the array: a valid identifier, at most 8 bytes, and
 * nothing after its data. */
static int check_raw_send(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	(void)code;
	for (size_t off = 0; off < len; off += sizeof(mbx_raw_frame)) {
		mbx_raw_frame f;

		memcpy(&f, p + off, sizeof f);
		if (!all_zero(f.pad, sizeof f.pad))
			return refuse(bad, MBX_BAD_RESERVED);
		if (!raw_id_ok(f.id) || f.len > 8)
			return refuse(bad, MBX_BAD_PARAM);
		if (!all_zero(f.data + f.len, 8u - f.len))
			return refuse(bad, MBX_BAD_RESERVED);
	}
	return 0;
}

/* 1010h/1011h: sub-index 1..127 */
/* APP_WATCHDOG: a withdrawal (0, 0), or an interval in bounds with a
 * set of known reactions, at most one NMT reaction (or the configured set
 * alone). */
static int check_app_wd(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_appwd_req r;
	uint32_t nmt;

	(void)code;
	(void)len;
	memcpy(&r, p, sizeof r);
	nmt = r.reactions & MBX_APPWD_R_NMT;
	if (!r.interval_ms)
		return r.reactions ? refuse(bad, MBX_BAD_PARAM) : 0;
	if (r.interval_ms < MBX_APPWD_INTERVAL_MIN_MS || r.interval_ms > MBX_APPWD_INTERVAL_MAX_MS)
		return refuse(bad, MBX_BAD_PARAM);
	if (r.reactions == MBX_APPWD_R_CONFIGURED)
		return 0;
	if (!r.reactions || (r.reactions & ~MBX_APPWD_R_ALL) || (nmt & (nmt - 1u)))
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

/* APP_HOLD, HOST_READY: a flag 0/1 and zero padding (same layout). */
static int check_app_flag(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	(void)code;
	if (p[0] > 1)
		return refuse(bad, MBX_BAD_PARAM);
	return all_zero(p + 1, len - 1) ? 0 : refuse(bad, MBX_BAD_RESERVED);
}

static int check_store_req(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_store_req r;

	(void)code, (void)len;
	memcpy(&r, p, sizeof r);
	if (!all_zero(r.pad, sizeof r.pad))
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.sub < 1 || r.sub > 127)
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

static int check_scan_req(uint16_t code, const uint8_t *p, size_t len, mbx_bad *bad)
{
	mbx_scan_req r;

	(void)code, (void)len;
	memcpy(&r, p, sizeof r);
	if (!all_zero(r.pad, sizeof r.pad))
		return refuse(bad, MBX_BAD_RESERVED);
	if (r.first < 1 || r.last > 127 || r.first > r.last ||
	    r.timeout_ms > MBX_SCAN_TIMEOUT_MAX_MS || r.parallel > 128)
		return refuse(bad, MBX_BAD_PARAM);
	return 0;
}

/* ---- command table ------------------------------------------------------- */

#define R 0
#define W MBX_CI_WRITE
#define S MBX_CI_SERVER
#define D MBX_CI_DATA
#define A MBX_CI_ARRAY
#define Q MBX_CI_QUIET

/* Sorted by code (binary search). The last column checks the fields of
 * the fixed part once its size is right (NULL: nothing to check; EMCY_SEND
 * takes any code and data). */
static const mbx_cmd_info cmd_table[] = {
	{ MBX_CMD_REGISTER, R | S, sizeof(mbx_register_req), 0, "register", check_register },
	{ MBX_CMD_UNREGISTER, R | S, 0, 0, "unregister", NULL },
	{ MBX_CMD_SUBSCRIBE, R | S, sizeof(mbx_subscribe_req), 0, "subscribe", check_subscribe },
	{ MBX_CMD_UNSUBSCRIBE, R | S, sizeof(mbx_unsubscribe_req), 0, "unsubscribe",
	  check_unsubscribe },
	{ MBX_CMD_PING, R | S, 0, 0, "ping", NULL },
	{ MBX_CMD_XFER_ACK, R | S | Q, sizeof(mbx_xfer_ack), 0, "xfer-ack", check_xfer_ack },
	{ MBX_CMD_MBX_STATS, R | S, 0, 0, "mbx-stats", NULL },
	{ MBX_CMD_OD_READ, R, sizeof(mbx_obj_req), 0, "od-read", check_obj_req },
	{ MBX_CMD_OD_WRITE, W | D, sizeof(mbx_obj_req), 0, "od-write", check_obj_req },
	{ MBX_CMD_SDO_UPLOAD, R, sizeof(mbx_sdo_req), 0, "sdo-upload", check_sdo_req },
	{ MBX_CMD_SDO_DOWNLOAD, W | D, sizeof(mbx_sdo_req), 0, "sdo-download", check_sdo_req },
	{ MBX_CMD_NMT, W, sizeof(mbx_nmt_req), 0, "nmt", check_nmt },
	{ MBX_CMD_NODE_TABLE, R, 0, 0, "node-table", NULL },
	{ MBX_CMD_NODE_SCAN, W, sizeof(mbx_scan_req), 0, "node-scan", check_scan_req },
	{ MBX_CMD_NODE_SCAN_CACHE, R, 0, 0, "node-scan-cache", NULL },
	{ MBX_CMD_PDO_REQUEST, W, sizeof(mbx_pdo_num_req), 0, "pdo-request", check_pdo_request },
	{ MBX_CMD_PDO_READ, R, sizeof(mbx_obj_req), 0, "pdo-read", check_obj_req },
	{ MBX_CMD_PDO_WRITE, W | D, sizeof(mbx_obj_req), 8, "pdo-write", check_obj_req },
	{ MBX_CMD_RPDO_STATUS, R, 0, 0, "rpdo-status", NULL },
	{ MBX_CMD_EMCY_SEND, W, sizeof(mbx_emcy_req), 0, "emcy-send", NULL },
	{ MBX_CMD_RAW_SEND, W | A, sizeof(mbx_raw_frame), MBX_RAW_SEND_MAX, "raw-send",
	  check_raw_send },
	{ MBX_CMD_LSS_SWITCH_GLOBAL, W, sizeof(mbx_lss_req), 0, "lss-switch-global", check_lss },
	{ MBX_CMD_LSS_SWITCH_SELECTIVE, W, sizeof(mbx_lss_req), 0, "lss-switch-selective",
	  check_lss },
	{ MBX_CMD_LSS_SET_NODE_ID, W, sizeof(mbx_lss_req), 0, "lss-set-node-id", check_lss },
	{ MBX_CMD_LSS_SET_BIT_TIMING, W, sizeof(mbx_lss_req), 0, "lss-set-bit-timing", check_lss },
	{ MBX_CMD_LSS_ACTIVATE_BIT_TIMING, W, sizeof(mbx_lss_req), 0, "lss-activate-bit-timing",
	  check_lss },
	{ MBX_CMD_LSS_STORE, W, sizeof(mbx_lss_req), 0, "lss-store", check_lss },
	{ MBX_CMD_LSS_INQUIRE, W, sizeof(mbx_lss_req), 0, "lss-inquire", check_lss },
	{ MBX_CMD_LSS_IDENTIFY_REMOTE, W, sizeof(mbx_lss_req), 0, "lss-identify-remote",
	  check_lss },
	{ MBX_CMD_LSS_IDENTIFY_NONCONF, W, sizeof(mbx_lss_req), 0, "lss-identify-nonconf",
	  check_lss },
	{ MBX_CMD_LSS_FASTSCAN, W, sizeof(mbx_lss_req), 0, "lss-fastscan", check_lss },
	{ MBX_CMD_LINE_STATUS, R, 0, 0, "line-status", NULL },
	{ MBX_CMD_LINE_HEALTH, R, 0, 0, "line-health", NULL },
	{ MBX_CMD_LINE_HEALTH_RESET, W, 0, 0, "line-health-reset", NULL },
	{ MBX_CMD_STORE, W, sizeof(mbx_store_req), 0, "store", check_store_req },
	{ MBX_CMD_RESTORE, W, sizeof(mbx_store_req), 0, "restore", check_store_req },
	{ MBX_CMD_MGR_STATUS, R, 0, 0, "manager-status", NULL },
	{ MBX_CMD_MGR_BOOT, W, sizeof(mbx_mgr_node_req), 0, "manager-boot", check_mgr_node_req },
	{ MBX_CMD_MGR_START, W, 0, 0, "manager-start", NULL },
	{ MBX_CMD_MGR_REQUEST_NMT, W, sizeof(mbx_mgr_nmt_req), 0, "manager-request-nmt",
	  check_mgr_request_nmt },
	{ MBX_CMD_MGR_NODE_DIAG, R, sizeof(mbx_mgr_node_req), 0, "manager-node-diag",
	  check_mgr_node_req },
	{ MBX_CMD_MGR_RESET_COUNTERS, W, 0, 0, "manager-reset-counters", NULL },
	{ MBX_CMD_MGR_PROGRAM, W | D, sizeof(mbx_mgr_program_req), 0, "manager-program",
	  check_mgr_program },
	{ MBX_CMD_MGR_NODE_SET, W | D, sizeof(mbx_mgr_node_set_req), 0, "manager-node-set",
	  check_mgr_node_set },
	{ MBX_CMD_GW_ROUTES, R, 0, 0, "gw-routes", NULL },
	{ MBX_CMD_GW_SDO_UPLOAD, R, sizeof(mbx_gw_sdo_req), 0, "gw-sdo-upload", check_gw_sdo_req },
	{ MBX_CMD_GW_SDO_DOWNLOAD, W | D, sizeof(mbx_gw_sdo_req), 0, "gw-sdo-download",
	  check_gw_sdo_req },
	{ MBX_CMD_DEV_LAYOUT, R, sizeof(mbx_dev_node_req), 0, "dev-layout", check_dev_node },
	{ MBX_CMD_DEV_WATCH, R, sizeof(mbx_dev_watch_req), 0, "dev-watch", check_dev_obj },
	{ MBX_CMD_DEV_UNWATCH, R, sizeof(mbx_dev_obj_req), 0, "dev-unwatch", check_dev_obj },
	{ MBX_CMD_DEV_READ, R, sizeof(mbx_dev_read_req), 0, "dev-read", check_dev_obj },
	{ MBX_CMD_DEV_WRITE, W | D, sizeof(mbx_dev_obj_req), 0, "dev-write", check_dev_obj },
	{ MBX_CMD_DEV_FORWARDS, R, 0, 0, "dev-forwards", NULL },
	{ MBX_CMD_APP_CLAIM, W | D, sizeof(mbx_app_claim_req), 0, "app-claim", check_app_claim },
	{ MBX_CMD_APP_RELEASE, W, sizeof(mbx_obj_req), 0, "app-release", check_app_release },
	{ MBX_CMD_APP_ANSWER, W | D, sizeof(mbx_app_answer_req), 0, "app-answer",
	  check_app_answer },
	{ MBX_CMD_APP_IND_DATA, W, sizeof(mbx_app_ind_req), 0, "app-ind-data", check_app_ind },
	{ MBX_CMD_APP_LIST, R, 0, 0, "app-list", NULL },
	{ MBX_CMD_APP_WATCHDOG, W, sizeof(mbx_appwd_req), 0, "app-watchdog", check_app_wd },
	{ MBX_CMD_APP_KEEPALIVE, W, 0, 0, "app-keepalive", NULL },
	{ MBX_CMD_APP_HOLD, W, sizeof(mbx_appwd_hold_req), 0, "app-hold", check_app_flag },
	{ MBX_CMD_HOST_READY, W, sizeof(mbx_host_ready_req), 0, "host-ready", check_app_flag },
	{ MBX_CMD_APP_STATUS, R, 0, 0, "app-status", NULL },
};

#undef R
#undef W
#undef S
#undef D
#undef A
#undef Q

const mbx_cmd_info *mbx_cmd_lookup(unsigned code)
{
	size_t lo = 0, hi = sizeof cmd_table / sizeof cmd_table[0];

	while (lo < hi) {
		size_t mid = (lo + hi) / 2;

		if (cmd_table[mid].code == code)
			return &cmd_table[mid];
		if (cmd_table[mid].code < code)
			lo = mid + 1;
		else
			hi = mid;
	}
	return NULL;
}

const char *mbx_cmd_to_string(unsigned code)
{
	const mbx_cmd_info *ci = mbx_cmd_lookup(code);

	return ci ? ci->name : "?";
}

/* The first chunk of a chunked command, or a later one. */
static int check_chunked(const mbx_cmd_info *ci, const mbx_hdr *h, const uint8_t *payload,
			 mbx_bad *bad)
{
	size_t len = h->len;

	/* only data-carrying commands with no size cap are chunked */
	if (!(ci->flags & MBX_CI_DATA) || ci->max_data)
		return refuse(bad, MBX_BAD_CHUNK);
	if (h->chunk > 0)
		return len ? 0 : refuse(bad, MBX_BAD_SIZE);
	/* first chunk: fixed part + some data, and more must follow
	 * (a transfer that fits one message is not chunked) */
	if (len < ci->fixed || !(h->flags & MBX_F_MORE) || h->total <= len - ci->fixed)
		return refuse(bad, MBX_BAD_CHUNK);
	return ci->check ? ci->check(h->code, payload, len, bad) : 0;
}

/* The size of a whole (unchunked) command's payload is wrong? */
static bool size_wrong(const mbx_cmd_info *ci, size_t len)
{
	if (ci->flags & MBX_CI_ARRAY)
		return len == 0 || len % ci->fixed || len / ci->fixed > ci->max_data;
	if (!(ci->flags & MBX_CI_DATA))
		return len != ci->fixed;
	if (len < ci->fixed)
		return true;
	return ci->max_data && (len - ci->fixed > ci->max_data || len == ci->fixed);
}

int mbx_cmd_validate(const mbx_hdr *h, const uint8_t *payload, mbx_bad *bad)
{
	const mbx_cmd_info *ci = mbx_cmd_lookup(h->code);

	if (bad)
		*bad = MBX_BAD_NONE;
	if (!ci)
		return refuse(bad, MBX_BAD_CMD);
	if (h->flags & MBX_F_CHUNKED)
		return check_chunked(ci, h, payload, bad);
	if (size_wrong(ci, h->len))
		return refuse(bad, MBX_BAD_SIZE);
	return ci->check ? ci->check(h->code, payload, h->len, bad) : 0;
}
