/* SPDX-License-Identifier: MIT */
/*
 * core/od_std.c - the standard communication objects (see od_std.h).
 *
 * The objects a service owns are created by that service's own
 * co_od_add_comm_defaults_*() helper, so that the layout the service hooks
 * at init and the layout created here cannot drift apart; this file adds
 * only the objects no service creates (1000h, 1008h..100Ah, 1010h/1011h,
 * 1018h, 1200h.., 1280h.., 1F2Ch/1F2Fh) and chooses the defaults.
 */
#include "core/od_std.h"

#include <errno.h>
#include <string.h>

#include "core/emcy.h"
#include "core/guarding.h"
#include "core/heartbeat.h"
#include "core/nmt.h"
#include "core/pdo.h"
#include "core/sdo.h"
#include "core/store.h"
#include "core/sync.h"
#include "core/time.h"

#define PDO_MAX 512u
#define SDO_CHANNELS_MAX 128u
#define COB_INVALID 0x80000000u

void co_od_std_opts_init(co_od_std_opts *o)
{
	memset(o, 0, sizeof(*o));
	o->device_name = "cogw";
	o->hw_version = "";
	o->sw_version = "";
	o->emcy_history = 8;
	o->emcy_consumers = 127;
	o->emcy_consume_all = true;
	o->hb_consumers = 127;
	o->sync_cob_id = 0x80;
	o->time_cob_id = 0x100;
	o->store_subs = 3;
	o->error_behaviour_subs = 1;
	o->sdo_servers = 1;
}

static int add_string(co_od *od, uint16_t idx, const char *s)
{
	size_t n = s ? strlen(s) : 0;
	int rc;

	if (n > CO_OD_STD_STRING_MAX)
		return -EINVAL;
	/* Capacity CO_OD_STD_STRING_MAX, not strlen: the configuration may
	 * replace the text later with its "values". */
	rc = co_od_add_bytes(od, idx, 0, CO_T_VISIBLE_STRING, CO_ACC_CO, CO_OD_STD_STRING_MAX, s,
			     (uint32_t)n, NULL);
	return rc == -EEXIST ? 0 : rc;
}

static int add_identity(co_od *od, const co_od_std_opts *o)
{
	const uint32_t v[4] = { o->vendor_id, o->product_code, o->revision, o->serial };
	int rc = co_od_ensure_num(od, 0x1018, 0, CO_T_UNSIGNED8, CO_ACC_CO, 4, CO_OBJ_RECORD);

	for (uint8_t s = 1; !rc && s <= 4; s++)
		rc = co_od_ensure_num(od, 0x1018, s, CO_T_UNSIGNED32, CO_ACC_RO, v[s - 1],
				      CO_OBJ_RECORD);
	return rc;
}

/* CiA 301 §7.5.2.13/14: sub 0 = highest sub, each sub reads as the
 * capability word; core/store.c installs the signature check. */
static int add_store(co_od *od, uint8_t subs)
{
	int rc = 0;

	for (uint16_t idx = CO_STORE_IDX_SAVE; !rc && idx <= CO_STORE_IDX_LOAD; idx++) {
		if (co_od_has_index(od, idx))
			continue;
		rc = co_od_add_array(od, idx, CO_T_UNSIGNED32, subs, CO_ACC_RW, CO_STORE_CAP_CMD);
	}
	return rc;
}

/* 1200h: the default SDO server's COB-IDs are fixed by the predefined
 * connection set, so they are read-only (CiA 301 §7.5.2.33). */
static int add_sdo_server_default(co_od *od, uint8_t node_id)
{
	int rc;

	if (co_od_has_index(od, SDO_SERVER_PARAM))
		return 0;
	rc = co_od_ensure_num(od, SDO_SERVER_PARAM, 0, CO_T_UNSIGNED8, CO_ACC_CO, 2, CO_OBJ_RECORD);
	if (!rc)
		rc = co_od_ensure_num(od, SDO_SERVER_PARAM, 1, CO_T_UNSIGNED32, CO_ACC_RO,
				      0x600u + node_id, CO_OBJ_RECORD);
	if (!rc)
		rc = co_od_ensure_num(od, SDO_SERVER_PARAM, 2, CO_T_UNSIGNED32, CO_ACC_RO,
				      0x580u + node_id, CO_OBJ_RECORD);
	return rc;
}

static int add_pdos(co_od *od, uint8_t node_id, co_pdo_dir dir, uint16_t n, bool valid)
{
	uint16_t comm = dir == CO_PDO_RX ? 0x1400 : 0x1800;
	int rc;

	for (uint16_t k = 1; k <= n; k++) {
		co_pdo_desc d = { .dir = dir, .nr = k, .tt = 255, .map_subs = 8 };

		if (co_od_has_index(od, (uint16_t)(comm + k - 1)))
			continue;
		if (k <= 4) {
			/* Predefined connection set (CiA 301 §7.3.3): RPDO k
			 * = 100h * (k + 1) + id (200h..500h), TPDO k = 100h *
			 * k + 80h + id (180h..480h). */
			d.cob_id = (dir == CO_PDO_RX ? 0x100u * (k + 1u) : 0x100u * k + 0x80u) +
				   node_id;
			if (!valid)
				d.cob_id |= COB_INVALID;
		} else {
			d.cob_id = COB_INVALID;
		}
		rc = co_od_add_pdo(od, &d);
		if (rc)
			return rc;
	}
	return 0;
}

static int add_emcy(co_od *od, uint8_t node_id, const co_od_std_opts *o)
{
	bool had_1028 = co_od_has_index(od, 0x1028);
	int rc = co_od_add_comm_defaults_emcy(od, node_id, o->emcy_history, o->emcy_consumers,
					      o->emcy_consume_all);
	co_od_entry *e;

	if (rc || had_1028)
		return rc;
	/* Our own EMCY is not something to consume. */
	e = co_od_find(od, 0x1028, node_id);
	if (e) {
		co_od_entry_set_default_raw(e, (0x80u + node_id) | COB_INVALID);
		co_od_entry_reset(e);
	}
	return 0;
}

static int add_gateway(co_od *od, uint8_t emcy_subs)
{
	int rc = 0;

	if (!co_od_has_index(od, 0x1F2C))
		rc = co_od_add_array(od, 0x1F2C, CO_T_UNSIGNED32, 127, CO_ACC_RW, 0);
	if (!rc && emcy_subs && !co_od_has_index(od, 0x1F2F))
		rc = co_od_add_array(od, 0x1F2F, CO_T_UNSIGNED32, emcy_subs, CO_ACC_RW, 0);
	return rc;
}

static int check_opts(uint8_t node_id, const co_od_std_opts *o)
{
	if (node_id < 1 || node_id > 127)
		return -EINVAL;
	if (o->sdo_servers < 1 || o->sdo_servers > SDO_CHANNELS_MAX ||
	    o->sdo_clients > SDO_CHANNELS_MAX)
		return -EINVAL;
	if (o->rpdos > PDO_MAX || o->tpdos > PDO_MAX)
		return -EINVAL;
	if (o->hb_consumers > 127 || o->emcy_consumers > 127 || o->store_subs > 127 ||
	    o->error_behaviour_subs < 1 || o->error_behaviour_subs > 254 || o->emcy_history > 254)
		return -EINVAL;
	return 0;
}

int co_od_add_std_comm(co_od *od, uint8_t node_id, const co_od_std_opts *opts)
{
	co_od_std_opts def;
	const co_od_std_opts *o = opts;
	int rc;

	if (!o) {
		co_od_std_opts_init(&def);
		o = &def;
	}
	if (!od || (rc = check_opts(node_id, o)))
		return -EINVAL;

	if ((rc = co_od_ensure_num(od, 0x1000, 0, CO_T_UNSIGNED32, CO_ACC_RO, o->device_type, 0)))
		return rc;
	if ((rc = add_emcy(od, node_id, o)))
		return rc;
	if ((rc = co_od_add_comm_defaults_sync(od, o->sync_cob_id, o->sync_period_us,
					       o->sync_overflow)))
		return rc;
	if ((rc = add_string(od, 0x1008, o->device_name)) ||
	    (rc = add_string(od, 0x1009, o->hw_version)) ||
	    (rc = add_string(od, 0x100A, o->sw_version)))
		return rc;
	if ((rc = co_od_add_comm_defaults_guard(od)))
		return rc;
	if (o->store_subs && (rc = add_store(od, o->store_subs)))
		return rc;
	if ((rc = co_od_add_comm_defaults_time(od, o->time_cob_id)))
		return rc;
	if ((rc = co_od_add_comm_defaults_hb(od, o->hb_consumers, o->heartbeat_ms)))
		return rc;
	if ((rc = add_identity(od, o)))
		return rc;
	if ((rc = co_od_add_comm_defaults_nmt(od, o->error_behaviour_subs)))
		return rc;
	if ((rc = add_sdo_server_default(od, node_id)))
		return rc;
	for (unsigned i = 1; i < o->sdo_servers; i++)
		if ((rc = sdo_param_od_add(od, (uint16_t)(SDO_SERVER_PARAM + i), CO_ACC_CO)))
			return rc;
	for (unsigned i = 0; i < o->sdo_clients; i++)
		if ((rc = sdo_param_od_add(od, (uint16_t)(SDO_CLIENT_PARAM + i), CO_ACC_CO)))
			return rc;
	if ((rc = add_pdos(od, node_id, CO_PDO_RX, o->rpdos, o->pdo_valid)) ||
	    (rc = add_pdos(od, node_id, CO_PDO_TX, o->tpdos, o->pdo_valid)))
		return rc;
	if (o->gateway && (rc = add_gateway(od, o->emcy_consumers)))
		return rc;
	return 0;
}
