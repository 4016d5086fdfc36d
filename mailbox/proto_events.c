/* SPDX-License-Identifier: MIT */
/*
 * mailbox/proto_events.c - the events of the wire format: one table row
 * per event kind (its code, name, class and payload layout), and the names
 * of the classes a subscription selects (docs/mailbox.md "Events").
 *
 * A new event kind is one row in event_kinds[]: its name, the class that
 * delivers it and the size of its payload (plus a check when the payload
 * carries a count of items); mbx_event_to_string(), mbx_event_class_of()
 * and mbx_event_validate() all read the table.
 */
#include "mailbox/proto.h"

#include <string.h>

/* A value event: mbx_dev_value and its bytes. */
static bool dev_value_ok(const uint8_t *p, size_t len)
{
	mbx_dev_value v;

	if (len < sizeof v)
		return false;
	memcpy(&v, p, sizeof v);
	return v.len <= MBX_DEV_VALUE_EVENT_MAX && len == sizeof v + v.len;
}

/* Application events: their fixed part, then inline_len bytes of a value
 * of `size` bytes. */
static bool app_ind_ok(const uint8_t *p, size_t len)
{
	return mbx_app_event_split(MBX_EV_APP_IND, p, len, NULL, NULL) == 0;
}

static bool app_written_ok(const uint8_t *p, size_t len)
{
	return mbx_app_event_split(MBX_EV_APP_WRITTEN, p, len, NULL, NULL) == 0;
}

/* A PDO event: mbx_ev_pdo and its n mapped values. */
static bool pdo_ok(const uint8_t *p, size_t len)
{
	mbx_ev_pdo e;

	if (len < sizeof e)
		return false;
	memcpy(&e, p, sizeof e);
	return e.n <= MBX_PDO_VALUES_MAX && len == sizeof e + (size_t)e.n * sizeof(mbx_pdo_value);
}

struct event_kind {
	uint16_t code;
	uint32_t cls;
	const char *name;
	size_t size;                                 /* the payload's, when no check */
	bool (*check)(const uint8_t *p, size_t len); /* a payload of varying size */
};

/* Sorted by code (binary search). */
static const struct event_kind event_kinds[] = {
	{ MBX_EV_OVERFLOW, MBX_EVC_OVERFLOW, "overflow", sizeof(mbx_ev_overflow), NULL },
	{ MBX_EV_OD_WRITTEN, MBX_EVC_OD, "od-written", sizeof(mbx_ev_od_written), NULL },
	{ MBX_EV_SDO_DONE, MBX_EVC_SDO, "sdo-done", sizeof(mbx_ev_sdo_done), NULL },
	{ MBX_EV_NMT_STATE, MBX_EVC_NMT, "nmt-state", sizeof(mbx_ev_node), NULL },
	{ MBX_EV_BOOTUP, MBX_EVC_BOOT, "boot-up", sizeof(mbx_ev_node), NULL },
	{ MBX_EV_HB_STARTED, MBX_EVC_HB, "hb-started", sizeof(mbx_ev_node), NULL },
	{ MBX_EV_HB_LOST, MBX_EVC_HB, "hb-lost", sizeof(mbx_ev_node), NULL },
	{ MBX_EV_DUP_NODE, MBX_EVC_NMT, "dup-node", sizeof(mbx_ev_dup_node), NULL },
	{ MBX_EV_GUARD_TOGGLE, MBX_EVC_HB, "guard-toggle", sizeof(mbx_ev_node), NULL },
	{ MBX_EV_LIFE_LOST, MBX_EVC_HB, "life-lost", sizeof(mbx_ev_node), NULL },
	{ MBX_EV_LIFE_RESUMED, MBX_EVC_HB, "life-resumed", sizeof(mbx_ev_node), NULL },
	{ MBX_EV_UNKNOWN_NODE, MBX_EVC_MANAGER, "unknown-node", sizeof(mbx_ev_unknown_node), NULL },
	{ MBX_EV_PDO, MBX_EVC_PDO, "pdo", 0, pdo_ok },
	{ MBX_EV_RPDO_FAULT, MBX_EVC_PDO_FAULT, "rpdo-fault", sizeof(mbx_ev_rpdo_fault), NULL },
	{ MBX_EV_RPDO_RECOVERED, MBX_EVC_PDO_FAULT, "rpdo-recovered", sizeof(mbx_ev_rpdo_fault),
	  NULL },
	{ MBX_EV_EMCY, MBX_EVC_EMCY, "emcy", sizeof(mbx_ev_emcy), NULL },
	{ MBX_EV_RAW, MBX_EVC_RAW, "raw", sizeof(mbx_ev_raw), NULL },
	{ MBX_EV_CAN_STATE, MBX_EVC_CAN, "can-state", sizeof(mbx_ev_can_state), NULL },
	{ MBX_EV_COMM_FAULT, MBX_EVC_CAN, "comm-fault", sizeof(mbx_ev_comm_fault), NULL },
	{ MBX_EV_MGR_STATE, MBX_EVC_MANAGER, "manager-state", sizeof(mbx_ev_mgr), NULL },
	{ MBX_EV_MGR_BOOT, MBX_EVC_BOOT, "manager-boot", sizeof(mbx_ev_mgr), NULL },
	{ MBX_EV_MGR_NODE, MBX_EVC_MANAGER, "manager-node", sizeof(mbx_ev_mgr), NULL },
	{ MBX_EV_GW_SDO, MBX_EVC_GW, "gw-sdo", sizeof(mbx_ev_gw_sdo), NULL },
	{ MBX_EV_GW_EMCY, MBX_EVC_GW, "gw-emcy", sizeof(mbx_ev_gw_emcy), NULL },
	{ MBX_EV_SYNC, MBX_EVC_SYNC, "sync", sizeof(mbx_ev_sync), NULL },
	{ MBX_EV_TIME, MBX_EVC_TIME, "time", sizeof(mbx_ev_time), NULL },
	{ MBX_EV_DEV_VALUE, MBX_EVC_VALUE, "dev-value", 0, dev_value_ok },
	{ MBX_EV_DEV_MIRROR, MBX_EVC_MANAGER, "dev-mirror", sizeof(mbx_ev_dev_mirror), NULL },
	{ MBX_EV_APP_IND, MBX_EVC_APP, "app-ind", 0, app_ind_ok },
	{ MBX_EV_APP_WRITTEN, MBX_EVC_APP, "app-written", 0, app_written_ok },
	{ MBX_EV_APP_CANCEL, MBX_EVC_APP, "app-cancel", sizeof(mbx_ev_app_cancel), NULL },
	{ MBX_EV_APP_WD_TIMEOUT, MBX_EVC_APP, "app-watchdog-timeout", sizeof(mbx_ev_appwd), NULL },
	{ MBX_EV_APP_NMT, MBX_EVC_APP, "app-nmt", sizeof(mbx_appwd_nmt), NULL },
	{ MBX_EV_HOST_STATE, MBX_EVC_APP, "host-state", sizeof(mbx_ev_host), NULL },
};

static const struct event_kind *event_kind_of(unsigned code)
{
	size_t lo = 0, hi = sizeof event_kinds / sizeof event_kinds[0];

	while (lo < hi) {
		size_t mid = (lo + hi) / 2;

		if (event_kinds[mid].code == code)
			return &event_kinds[mid];
		if (event_kinds[mid].code < code)
			lo = mid + 1;
		else
			hi = mid;
	}
	return NULL;
}

const char *mbx_event_to_string(unsigned code)
{
	const struct event_kind *k = event_kind_of(code);

	return k ? k->name : "?";
}

uint32_t mbx_event_class_of(unsigned code)
{
	const struct event_kind *k = event_kind_of(code);

	return k ? k->cls : 0;
}

int mbx_event_validate(unsigned code, const uint8_t *p, size_t len)
{
	const struct event_kind *k = event_kind_of(code);

	if (!k)
		return MBX_E_UNKNOWN_CMD;
	if (k->check ? k->check(p, len) : len == k->size)
		return 0;
	return MBX_E_MALFORMED;
}

const char *mbx_event_class_to_string(uint32_t cls)
{
	/* by bit number */
	static const char *const names[32] = {
		[0] = "nmt",       [1] = "hb",         [2] = "boot",     [3] = "emcy",
		[4] = "pdo",       [5] = "sdo",        [6] = "can",      [7] = "raw",
		[8] = "od",        [9] = "manager",    [10] = "gateway", [11] = "sync",
		[12] = "time",     [13] = "pdo-fault", [14] = "value",   [15] = "app",
		[31] = "overflow",
	};
	unsigned bit = 0;

	if (cls == 0 || (cls & (cls - 1)) != 0)
		return "?"; /* not a single class */
	while (!(cls >> bit & 1u))
		bit++;
	return names[bit] ? names[bit] : "?";
}

int mbx_app_event_split(unsigned code, const void *p, size_t len, void *fixed, const uint8_t **data)
{
	mbx_ev_app_ind ind;
	mbx_ev_app_written w;
	size_t fixed_len = code == MBX_EV_APP_IND ? sizeof ind : sizeof w;
	uint16_t inline_len;
	uint32_t size;

	if ((code != MBX_EV_APP_IND && code != MBX_EV_APP_WRITTEN) || len < fixed_len)
		return MBX_E_MALFORMED;
	if (code == MBX_EV_APP_IND) {
		memcpy(&ind, p, sizeof ind);
		inline_len = ind.inline_len;
		size = ind.size;
	} else {
		memcpy(&w, p, sizeof w);
		inline_len = w.inline_len;
		size = w.size;
	}
	if (inline_len > size || len != fixed_len + inline_len)
		return MBX_E_MALFORMED;
	if (fixed)
		memcpy(fixed, p, fixed_len);
	if (data)
		*data = (const uint8_t *)p + fixed_len;
	return 0;
}

bool mbx_raw_filter_match(const mbx_raw_filter *f, const mbx_raw_frame *fr)
{
	return (((fr->id) ^ f->id) & f->mask) == 0;
}
