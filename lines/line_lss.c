/* SPDX-License-Identifier: MIT */
/*
 * lines/line_lss.c - mailbox LSS_* commands (CiA 305) through the line's
 * LSS master (core/lss_master.c). The whole transaction is here:
 * lss_command() parks the request in a pending slot and submits it with
 * lss_done() as its confirmation; lss_done() answers the requester.
 */
#include "lines/line_internal.h"

#include <errno.h>
#include <string.h>

#include "core/lss_master.h"

/* LSS_INQUIRE: `what` is the LSS command specifier of the inquiry. */
static lss_master_service inquire_service_of(uint8_t what)
{
	switch (what) {
	case LSS_CS_INQUIRE_VENDOR:
		return LSS_SVC_INQUIRE_VENDOR;
	case LSS_CS_INQUIRE_PRODUCT:
		return LSS_SVC_INQUIRE_PRODUCT;
	case LSS_CS_INQUIRE_REVISION:
		return LSS_SVC_INQUIRE_REVISION;
	case LSS_CS_INQUIRE_SERIAL:
		return LSS_SVC_INQUIRE_SERIAL;
	case LSS_CS_INQUIRE_NODE_ID:
		return LSS_SVC_INQUIRE_NODE_ID;
	}
	return LSS_SVC_NONE;
}

static lss_master_service lss_service_of(uint16_t code, uint8_t what)
{
	switch (code) {
	case MBX_CMD_LSS_SWITCH_GLOBAL:
		return LSS_SVC_SWITCH_GLOBAL;
	case MBX_CMD_LSS_SWITCH_SELECTIVE:
		return LSS_SVC_SWITCH_SELECTIVE;
	case MBX_CMD_LSS_SET_NODE_ID:
		return LSS_SVC_CONFIG_NODE_ID;
	case MBX_CMD_LSS_SET_BIT_TIMING:
		return LSS_SVC_CONFIG_BIT_TIMING;
	case MBX_CMD_LSS_ACTIVATE_BIT_TIMING:
		return LSS_SVC_ACTIVATE_BIT_TIMING;
	case MBX_CMD_LSS_STORE:
		return LSS_SVC_STORE;
	case MBX_CMD_LSS_IDENTIFY_REMOTE:
		return LSS_SVC_IDENTIFY_REMOTE;
	case MBX_CMD_LSS_IDENTIFY_NONCONF:
		return LSS_SVC_IDENTIFY_NON_CONFIGURED;
	case MBX_CMD_LSS_FASTSCAN:
		return LSS_SVC_FASTSCAN;
	case MBX_CMD_LSS_INQUIRE:
		return inquire_service_of(what);
	}
	return LSS_SVC_NONE;
}

static int status_of(lss_result r)
{
	switch (r) {
	case LSS_RESULT_OK:
		return 0;
	case LSS_RESULT_SLAVE_ERROR:
		return MBX_E_LSS;
	case LSS_RESULT_TIMEOUT:
		return MBX_E_NO_ANSWER; /* the slave, not us */
	case LSS_RESULT_NOT_FOUND:
		return MBX_E_NOT_FOUND;
	default:
		return MBX_E_STATE;
	}
}

/* The LSS master confirms the service (exactly once, on the line thread,
 * never inside lss_master_submit). */
static void lss_done(void *arg, const co_ev_lss_master *m)
{
	line *l = arg;
	line_pending *pp = line_pending_find(&l->pending, m->tag);
	if (!pp)
		return; /* its client went away meanwhile */
	mbx_lss_resp resp = {
		.error = m->error_code,
		.spec_error = m->error_spec,
		.found = m->result == LSS_RESULT_OK && m->answers > 0,
		.value = m->service == LSS_SVC_INQUIRE_NODE_ID ? m->node_id : m->value,
	};
	memcpy(resp.id, m->identity, sizeof resp.id);
	line_answer(l, &pp->reply, status_of((lss_result)m->result), 0, &resp, sizeof resp);
	line_pending_release(&l->pending, pp);
}

void line_lss_command(line *l, const mbx_request *req)
{
	mbx_lss_req q;
	memcpy(&q, req->payload, sizeof q);
	lss_master_service svc = lss_service_of(req->code, q.what);
	if (svc == LSS_SVC_NONE)
		return line_answer(l, &req->reply, MBX_E_PARAM, 0, NULL, 0);
	line_pending *pp = line_pending_take(&l->pending, req, LINE_PENDING_LSS, false);
	if (!pp)
		return line_answer(l, &req->reply, MBX_E_BUSY, 0, NULL, 0);
	lss_master_req r = {
		.service = svc,
		.tag = pp->tag,
		.timeout_ms = q.timeout_ms,
		.mode = q.mode,
		.node_id = q.node,
		.table = q.table,
		.index = q.bit_index,
		.delay_ms = q.delay_ms,
		.addr = { .id = { q.vendor, q.product, q.rev_lo, q.ser_lo } },
		.addr_high = { .id = { q.vendor, q.product, q.rev_hi, q.ser_hi } },
		.con = lss_done,
		.con_arg = l,
	};
	int rc = lss_master_submit(l->node, &r, l->now_us);
	if (rc < 0) {
		line_pending_release(&l->pending, pp);
		line_answer(l, &req->reply, mbx_status_of_errno(rc), 0, NULL, 0);
	}
}

void line_lss_client_gone(line *l, uint32_t client)
{
	/* LSS services are short and the master runs one at a time: the
	 * running one finishes (its answer is dropped in lss_done), the slot
	 * is free at once. */
	for (unsigned i = 0; i < LINE_PENDING_MAX; i++) {
		line_pending *pp = line_pending_at(&l->pending, i);
		if (pp->used && pp->kind == LINE_PENDING_LSS && pp->reply.client == client)
			line_pending_release(&l->pending, pp);
	}
}
