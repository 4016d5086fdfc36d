/* SPDX-License-Identifier: MIT */
/*
 * apps/cosim/device.c - a JSON device file (docs/cosim.md) turned into an
 * object dictionary and a description of the simulated behaviour.
 *
 * The OD is built in layers, each reused from where it already lives:
 * core/od_std.c for the standard communication objects (so the simulated
 * slave carries exactly the objects, types and defaults the core's services
 * expect), core/pdo.c's co_od_add_pdo() for the PDO records, and
 * apps/common/json_od.c for the device's own "objects" and "values" (the
 * same shapes as cogwd's configuration). Every check names the JSON path,
 * "etc/devices/x.json: tpdos[0].map[1]: ...", as the daemon's config does.
 */
#include "apps/cosim/cosim.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "apps/common/json_od.h"
#include "apps/common/json_util.h"
#include "core/od_std.h"
#include "core/pdo.h"

const char *cosim_signal_kind_to_string(cosim_signal_kind k)
{
	switch (k) {
	case COSIM_SIG_CONST:
		return "const";
	case COSIM_SIG_RAMP:
		return "ramp";
	case COSIM_SIG_SINE:
		return "sine";
	case COSIM_SIG_SQUARE:
		return "square";
	}
	return "?";
}

static bool signal_kind_from_string(const char *s, cosim_signal_kind *k)
{
	for (int i = COSIM_SIG_CONST; i <= COSIM_SIG_SQUARE; i++) {
		if (!strcmp(s, cosim_signal_kind_to_string((cosim_signal_kind)i))) {
			*k = (cosim_signal_kind)i;
			return true;
		}
	}
	return false;
}

/* "0x2003:00", "2003:0", "0x2003" (sub 0). Index and sub are hex, with or
 * without 0x, because that is how every CANopen document writes them. */
int cosim_parse_object(const char *s, uint16_t *index, uint8_t *sub)
{
	char *end;
	unsigned long i, sb = 0;

	if (!s || !*s)
		return -EINVAL;
	i = strtoul(s, &end, 16);
	if (end == s || i < 1 || i > 0xFFFF)
		return -EINVAL;
	if (*end == ':') {
		const char *p = end + 1;
		sb = strtoul(p, &end, 16);
		if (end == p || sb > 0xFF)
			return -EINVAL;
	}
	if (*end)
		return -EINVAL;
	*index = (uint16_t)i;
	*sub = (uint8_t)sb;
	return 0;
}

/* "0x2003:00:32": object and length in bits (decimal, 1..64). */
static int parse_map_entry(const char *s, uint32_t *out)
{
	char obj[32];
	const char *colon = strrchr(s, ':');
	char *end;
	uint16_t index;
	uint8_t sub;

	if (!colon || colon == s || (size_t)(colon - s) >= sizeof obj)
		return -EINVAL;
	memcpy(obj, s, (size_t)(colon - s));
	obj[colon - s] = 0;
	if (!strchr(obj, ':') || cosim_parse_object(obj, &index, &sub))
		return -EINVAL;
	unsigned long bits = strtoul(colon + 1, &end, 10);
	if (end == colon + 1 || *end || bits < 1 || bits > 64)
		return -EINVAL;
	*out = CO_PDO_MAP(index, sub, bits);
	return 0;
}

/* An object reference member: "0x2003:00". */
static int get_object(const cJSON *o, const char *key, const char *path, bool required,
		      uint16_t *index, uint8_t *sub, char *err, size_t errlen)
{
	const cJSON *v = json_util_get(o, key);
	char p[JSON_PATH_MAX];

	json_util_path_key(p, sizeof p, path, key);
	if (!v) {
		if (required)
			return json_util_fail(err, errlen, p, "required key is missing");
		*index = 0;
		*sub = 0;
		return 0;
	}
	if (!cJSON_IsString(v) || cosim_parse_object(v->valuestring, index, sub))
		return json_util_fail(
			err, errlen, p,
			"expected an object as \"0xINDEX:SUB\" (hex), e.g. \"0x2003:00\"");
	return 0;
}

/* A reference to an object that must exist and be numeric. */
static int check_numeric(const co_od *od, uint16_t index, uint8_t sub, const char *path,
			 const char *key, char *err, size_t errlen)
{
	char p[JSON_PATH_MAX];
	const co_od_entry *e = co_od_find(od, index, sub);

	json_util_path_key(p, sizeof p, path, key);
	if (!e)
		return json_util_fail(err, errlen, p, "object 0x%04X:%02X does not exist", index,
				      sub);
	if (co_type_is_variable((co_type)e->type))
		return json_util_fail(err, errlen, p, "object 0x%04X:%02X is a %s, not a number",
				      index, sub, co_type_to_string((co_type)e->type));
	return 0;
}

/* ---- top level ------------------------------------------------------------ */

static const char *const top_keys[] = { "name",         "comment",      "node_id",    "identity",
					"device_type",  "device_name",  "hw_version", "sw_version",
					"heartbeat_ms", "emcy_history", "store_subs", "objects",
					"values",       "tpdos",        "rpdos",      "lss",
					"signals",      "loopback",     "program",    NULL };

struct parsed_top {
	co_od_std_opts std;
	char device_name[CO_OD_STD_STRING_MAX];
	char hw[CO_OD_STD_STRING_MAX];
	char sw[CO_OD_STD_STRING_MAX];
};

static int parse_identity(const cJSON *root, struct parsed_top *t, char *err, size_t errlen)
{
	static const char *const keys[] = { "vendor", "product", "revision",
					    "serial", "comment", NULL };
	const cJSON *id = json_util_get(root, "identity");
	uint64_t v[4] = { 0, 0, 0, 0 };
	int rc;
	const json_at at = { "identity", err, errlen };

	if (!id)
		return 0;
	if ((rc = json_util_check_object(id, &at, keys)) ||
	    (rc = json_util_opt_uint(id, "vendor", &at, 0, UINT32_MAX, &v[0])) ||
	    (rc = json_util_opt_uint(id, "product", &at, 0, UINT32_MAX, &v[1])) ||
	    (rc = json_util_opt_uint(id, "revision", &at, 0, UINT32_MAX, &v[2])) ||
	    (rc = json_util_opt_uint(id, "serial", &at, 0, UINT32_MAX, &v[3])))
		return rc;
	t->std.vendor_id = (uint32_t)v[0];
	t->std.product_code = (uint32_t)v[1];
	t->std.revision = (uint32_t)v[2];
	t->std.serial = (uint32_t)v[3];
	return 0;
}

static int parse_top(const cJSON *root, cosim_device *dev, const cosim_device_opts *opts,
		     struct parsed_top *t, char *err, size_t errlen)
{
	uint64_t node = 1, dt = 0, hb = 0, hist = 8, store = 1;
	int rc;
	const json_at at = { "", err, errlen };

	co_od_std_opts_init(&t->std);
	snprintf(t->device_name, sizeof t->device_name, "cosim");
	t->hw[0] = t->sw[0] = 0;
	if ((rc = json_util_check_object(root, &at, top_keys)) ||
	    (rc = json_util_opt_string(root, "name", &at, 1, dev->name, sizeof dev->name)) ||
	    (rc = json_util_opt_uint(root, "node_id", &at, 1, 255, &node)) ||
	    (rc = json_util_opt_uint(root, "device_type", &at, 0, UINT32_MAX, &dt)) ||
	    (rc = json_util_opt_string(root, "device_name", &at, 0, t->device_name,
				       sizeof t->device_name)) ||
	    (rc = json_util_opt_string(root, "hw_version", &at, 0, t->hw, sizeof t->hw)) ||
	    (rc = json_util_opt_string(root, "sw_version", &at, 0, t->sw, sizeof t->sw)) ||
	    (rc = json_util_opt_uint(root, "heartbeat_ms", &at, 0, 0xFFFF, &hb)) ||
	    (rc = json_util_opt_uint(root, "emcy_history", &at, 0, 254, &hist)) ||
	    (rc = json_util_opt_uint(root, "store_subs", &at, 0, 127, &store)) ||
	    (rc = parse_identity(root, t, err, errlen)))
		return rc;
	if (node > 127 && node != 255)
		return json_util_fail(err, errlen, "node_id",
				      "%llu is out of range 1..127 (or 255 = unconfigured)",
				      (unsigned long long)node);
	if (opts && opts->node_id >= 0)
		node = (uint64_t)opts->node_id;
	if (opts && opts->serial >= 0)
		t->std.serial = (uint32_t)opts->serial;
	if (!dev->name[0])
		snprintf(dev->name, sizeof dev->name, "%s", t->device_name);
	dev->node_id = (uint8_t)node;
	t->std.device_type = (uint32_t)dt;
	t->std.device_name = t->device_name;
	t->std.hw_version = t->hw;
	t->std.sw_version = t->sw;
	t->std.heartbeat_ms = (uint16_t)hb;
	t->std.emcy_history = (uint8_t)hist;
	/* A device: it produces EMCY and heartbeats, it does not consume
	 * them (the manager does). */
	t->std.emcy_consumers = 0;
	t->std.hb_consumers = 0;
	t->std.store_subs = (uint8_t)store;
	t->std.rpdos = t->std.tpdos = 0; /* built from "tpdos"/"rpdos" below */
	return 0;
}

/* ---- PDOs ------------------------------------------------------------------- */

static const char *const pdo_keys[] = {
	"nr",         "cob_id", "add_node_id", "valid", "transmission", "inhibit_100us", "event_ms",
	"sync_start", "map",    "comment",     NULL
};

static void add_rel(cosim_device *dev, uint16_t index, uint8_t sub, uint32_t base)
{
	if (dev->n_rel < COSIM_REL_COB_MAX)
		dev->rel[dev->n_rel++] = (cosim_rel_cob){ index, sub, base };
}

static int parse_map(const cJSON *m, const co_od *od, co_pdo_dir dir, const char *path,
		     uint32_t *map, uint8_t *n_map, char *err, size_t errlen)
{
	char p[JSON_PATH_MAX], ip[JSON_PATH_MAX];
	const cJSON *it;
	unsigned bits = 0;
	size_t i = 0;

	*n_map = 0;
	if (!m)
		return 0;
	json_util_path_key(p, sizeof p, path, "map");
	if (!cJSON_IsArray(m))
		return json_util_fail(err, errlen, p, "expected an array of \"0xINDEX:SUB:BITS\"");
	cJSON_ArrayForEach(it, m)
	{
		json_util_path_index(ip, sizeof ip, p, i++);
		if (i > 8)
			return json_util_fail(err, errlen, ip, "more than 8 mapping entries");
		if (!cJSON_IsString(it) || parse_map_entry(it->valuestring, &map[i - 1]))
			return json_util_fail(err, errlen, ip,
					      "expected \"0xINDEX:SUB:BITS\" (hex object, decimal "
					      "bits), e.g. \"0x2003:00:32\"");
		uint16_t index = (uint16_t)(map[i - 1] >> 16);
		uint8_t sub = (uint8_t)(map[i - 1] >> 8);
		unsigned len = map[i - 1] & 0xFF;
		const co_od_entry *e = co_od_find(od, index, sub);
		bits += len;
		if (dir == CO_PDO_RX && index >= 1 && index <= 7)
			continue; /* dummy entry */
		if (!e)
			return json_util_fail(err, errlen, ip, "object 0x%04X:%02X does not exist",
					      index, sub);
		if (!(e->access & (dir == CO_PDO_TX ? CO_ACC_TPDO : CO_ACC_RPDO)))
			return json_util_fail(err, errlen, ip,
					      "object 0x%04X:%02X cannot be mapped into a%s (give "
					      "it \"pdo\": true%s)",
					      index, sub, dir == CO_PDO_TX ? " TPDO" : "n RPDO",
					      dir == CO_PDO_RX ? " and a writable access" : "");
		if (!co_type_is_variable((co_type)e->type) && len > e->size * 8u)
			return json_util_fail(
				err, errlen, ip, "%u bits is longer than the object (%s, %u bits)",
				len, co_type_to_string((co_type)e->type), e->size * 8u);
	}
	if (bits > 64)
		return json_util_fail(err, errlen, p, "%u bits do not fit one CAN frame (64)",
				      bits);
	*n_map = (uint8_t)(i);
	return 0;
}

/* The PDOs of one direction being read, and where errors go. */
struct pdo_read {
	cosim_device *dev;
	co_pdo_dir dir;
	char *err;
	size_t errlen;
};

/* The keys of one PDO object, defaults applied. */
struct pdo_keys {
	uint64_t nr, cob, tt, inhibit, event, start;
	bool add_id, valid;
};

/* The transmission type and the COB-ID of PDO keys k (at p) fit. */
static int pdo_keys_check(const struct pdo_read *r, const char *p, const struct pdo_keys *k)
{
	char *err = r->err;
	size_t errlen = r->errlen;

	if ((k->tt >= 241 && k->tt <= 251) ||
	    (r->dir == CO_PDO_RX && (k->tt == 252 || k->tt == 253))) {
		char tp[JSON_PATH_MAX];
		json_util_path_key(tp, sizeof tp, p, "transmission");
		return json_util_fail(
			err, errlen, tp, "%llu is a reserved transmission type for a%s",
			(unsigned long long)k->tt, r->dir == CO_PDO_TX ? " TPDO" : "n RPDO");
	}
	if (k->add_id && k->cob + 127 > 0x7FF)
		return json_util_fail(err, errlen, p,
				      "cob_id 0x%llX + node-ID does not fit 11 bits",
				      (unsigned long long)k->cob);
	return 0;
}

/* The keys of PDO it (at p; nr i + 1 unless it says) into k, checked. */
static int pdo_keys_read(const struct pdo_read *r, const cJSON *it, const char *p, size_t i,
			 struct pdo_keys *k)
{
	char *err = r->err;
	size_t errlen = r->errlen;
	int rc;
	const json_at at = { p, err, errlen };

	*k = (struct pdo_keys){ .nr = i + 1, .tt = 254, .add_id = true, .valid = true };
	if ((rc = json_util_check_object(it, &at, pdo_keys)) ||
	    (rc = json_util_opt_uint(it, "nr", &at, 1, COSIM_PDO_MAX, &k->nr)))
		return rc;
	/* Default COB-ID: the predefined connection set for PDO 1..4
	 * (CiA 301 §7.3.5), the caller must give one for the others. */
	if (k->nr <= 4)
		k->cob = r->dir == CO_PDO_TX ? CO_PDO_TPDO_DEFAULT_COB(k->nr, 0)
					     : CO_PDO_RPDO_DEFAULT_COB(k->nr, 0);
	else if (!json_util_get(it, "cob_id"))
		return json_util_fail(err, errlen, p,
				      "\"cob_id\" is required for PDO %llu (only 1..4 have "
				      "predefined ones)",
				      (unsigned long long)k->nr);
	if ((rc = json_util_opt_uint(it, "cob_id", &at, 1, 0x7FF, &k->cob)) ||
	    (rc = json_util_opt_bool(it, "add_node_id", &at, &k->add_id)) ||
	    (rc = json_util_opt_bool(it, "valid", &at, &k->valid)) ||
	    (rc = json_util_opt_uint(it, "transmission", &at, 0, 255, &k->tt)) ||
	    (rc = json_util_opt_uint(it, "inhibit_100us", &at, 0, 0xFFFF, &k->inhibit)) ||
	    (rc = json_util_opt_uint(it, "event_ms", &at, 0, 0xFFFF, &k->event)) ||
	    (rc = json_util_opt_uint(it, "sync_start", &at, 0, 255, &k->start)))
		return rc;
	return pdo_keys_check(r, p, k);
}

/* PDO it (at p) with keys k into the device's OD. */
static int pdo_add(const struct pdo_read *r, const cJSON *it, const char *p,
		   const struct pdo_keys *k)
{
	cosim_device *dev = r->dev;
	uint8_t id = dev->node_id == 255 ? 0 : dev->node_id;
	uint32_t map[8];
	co_pdo_desc d;
	int rc;

	memset(&d, 0, sizeof d);
	if ((rc = parse_map(json_util_get(it, "map"), dev->od, r->dir, p, map, &d.n_map, r->err,
			    r->errlen)))
		return rc;
	uint32_t base = (uint32_t)k->cob | (k->valid ? 0 : CO_PDO_COB_INVALID);
	d.dir = r->dir;
	d.nr = (uint16_t)k->nr;
	d.cob_id = base + (k->add_id ? id : 0);
	if (k->add_id && dev->node_id == 255)
		d.cob_id |= CO_PDO_COB_INVALID;
	d.tt = (uint8_t)k->tt;
	d.inhibit_100us = (uint16_t)k->inhibit;
	d.event_ms = (uint16_t)k->event;
	d.sync_start = (uint8_t)k->start;
	d.map_subs = 8;
	d.map = map;
	rc = co_od_add_pdo(dev->od, &d);
	if (rc == -EEXIST)
		return json_util_fail(r->err, r->errlen, p, "%s %llu is defined twice",
				      r->dir == CO_PDO_TX ? "TPDO" : "RPDO",
				      (unsigned long long)k->nr);
	if (rc == -ENOMEM)
		return rc;
	if (rc)
		return json_util_fail(r->err, r->errlen, p, "cannot build the PDO records (%s)",
				      strerror(-rc));
	if (k->add_id)
		add_rel(dev,
			(uint16_t)((r->dir == CO_PDO_TX ? CO_PDO_TPDO_COMM : CO_PDO_RPDO_COMM) +
				   k->nr - 1),
			1, base);
	return 0;
}

static int parse_pdos(const cJSON *root, cosim_device *dev, co_pdo_dir dir, char *err,
		      size_t errlen)
{
	const char *key = dir == CO_PDO_TX ? "tpdos" : "rpdos";
	const cJSON *arr = json_util_get(root, key), *it;
	const struct pdo_read r = { dev, dir, err, errlen };
	char p[JSON_PATH_MAX];
	size_t i = 0;
	int rc;

	if (!arr)
		return 0;
	if (!cJSON_IsArray(arr))
		return json_util_fail(err, errlen, key, "expected an array of PDO objects");
	cJSON_ArrayForEach(it, arr)
	{
		struct pdo_keys k;

		json_util_path_index(p, sizeof p, key, i);
		if ((rc = pdo_keys_read(&r, it, p, i++, &k)) || (rc = pdo_add(&r, it, p, &k)))
			return rc;
	}
	return 0;
}

/* ---- LSS ---------------------------------------------------------------------- */

static int parse_lss(const cJSON *root, cosim_device *dev, char *err, size_t errlen)
{
	static const char *const keys[] = { "enabled", "constant_id", "bit_timing", "comment",
					    NULL };
	const cJSON *l = json_util_get(root, "lss"), *bt, *it;
	char p[JSON_PATH_MAX], ip[JSON_PATH_MAX];
	size_t i = 0;
	int rc;
	const json_at at = { "lss", err, errlen };
	const json_at at_ip = { ip, err, errlen };

	dev->lss_enabled = true;
	if (!l)
		return 0;
	if ((rc = json_util_check_object(l, &at, keys)) ||
	    (rc = json_util_opt_bool(l, "enabled", &at, &dev->lss_enabled)) ||
	    (rc = json_util_opt_bool(l, "constant_id", &at, &dev->lss_constant_id)))
		return rc;
	bt = json_util_get(l, "bit_timing");
	if (!bt)
		return 0;
	json_util_path_key(p, sizeof p, "lss", "bit_timing");
	if (!cJSON_IsArray(bt) || cJSON_GetArraySize(bt) == 0)
		return json_util_fail(err, errlen, p,
				      "expected a non-empty array of CiA table indexes 0..8");
	cJSON_ArrayForEach(it, bt)
	{
		uint64_t v;
		json_util_path_index(ip, sizeof ip, p, i++);
		if ((rc = json_util_uint(it, &at_ip, 0, 8, false, &v)))
			return rc;
		if (v == 5)
			return json_util_fail(err, errlen, ip, "index 5 is reserved (CiA 305)");
		dev->lss_bit_timing_mask |= (uint16_t)(1u << v);
	}
	return 0;
}

/* ---- signals and loopback ------------------------------------------------------ */

static const char *const signal_keys[] = { "name",   "object",        "kind",        "min",
					   "max",    "value",         "period_ms",   "update_ms",
					   "notify", "offset_object", "span_object", "comment",
					   NULL };

static int opt_real(const cJSON *o, const char *key, const char *path, double *out, bool required,
		    char *err, size_t errlen)
{
	char p[JSON_PATH_MAX];
	const cJSON *v = json_util_get(o, key);
	const json_at at = { p, err, errlen };

	json_util_path_key(p, sizeof p, path, key);
	if (!v)
		return required ? json_util_fail(err, errlen, p, "required key is missing") : 0;
	return json_util_real(v, &at, out);
}

/* The scaling objects of signal s (at p), when it names them, are numbers. */
static int check_scaling(const cosim_device *dev, const cosim_signal_desc *s, const char *p,
			 char *err, size_t errlen)
{
	int rc;

	if (s->offset_index && (rc = check_numeric(dev->od, s->offset_index, s->offset_sub, p,
						   "offset_object", err, errlen)))
		return rc;
	if (s->span_index && (rc = check_numeric(dev->od, s->span_index, s->span_sub, p,
						 "span_object", err, errlen)))
		return rc;
	return 0;
}

static int parse_signal(const cJSON *it, const char *p, cosim_device *dev, cosim_signal_desc *s,
			char *err, size_t errlen)
{
	char kp[JSON_PATH_MAX], kind[16] = "const";
	uint64_t period = 0, update = 100;
	int rc;
	const json_at at = { p, err, errlen };

	memset(s, 0, sizeof *s);
	if ((rc = json_util_check_object(it, &at, signal_keys)) ||
	    (rc = json_util_opt_string(it, "name", &at, 1, s->name, sizeof s->name)) ||
	    (rc = get_object(it, "object", p, true, &s->index, &s->sub, err, errlen)) ||
	    (rc = check_numeric(dev->od, s->index, s->sub, p, "object", err, errlen)) ||
	    (rc = json_util_opt_string(it, "kind", &at, 1, kind, sizeof kind)) ||
	    (rc = json_util_opt_uint(it, "period_ms", &at, 1, 86400000, &period)) ||
	    (rc = json_util_opt_uint(it, "update_ms", &at, 1, 3600000, &update)) ||
	    (rc = json_util_opt_bool(it, "notify", &at, &s->notify)) ||
	    (rc = get_object(it, "offset_object", p, false, &s->offset_index, &s->offset_sub, err,
			     errlen)) ||
	    (rc = get_object(it, "span_object", p, false, &s->span_index, &s->span_sub, err,
			     errlen)))
		return rc;
	json_util_path_key(kp, sizeof kp, p, "kind");
	if (!signal_kind_from_string(kind, &s->kind))
		return json_util_fail(err, errlen, kp,
				      "unknown kind \"%s\" (const, ramp, sine or square)", kind);
	if ((rc = check_scaling(dev, s, p, err, errlen)))
		return rc;
	if (s->kind == COSIM_SIG_CONST) {
		if ((rc = opt_real(it, "value", p, &s->value, true, err, errlen)))
			return rc;
	} else {
		if ((rc = opt_real(it, "min", p, &s->min, true, err, errlen)) ||
		    (rc = opt_real(it, "max", p, &s->max, true, err, errlen)))
			return rc;
		json_util_path_key(kp, sizeof kp, p, "period_ms");
		if (!period)
			return json_util_fail(err, errlen, kp, "required for a %s signal", kind);
		json_util_path_key(kp, sizeof kp, p, "max");
		if (s->max < s->min)
			return json_util_fail(err, errlen, kp, "%g is below min %g", s->max,
					      s->min);
	}
	s->period_ms = (uint32_t)period;
	s->update_ms = (uint32_t)update;
	return 0;
}

static int parse_signals(const cJSON *root, cosim_device *dev, char *err, size_t errlen)
{
	const cJSON *arr = json_util_get(root, "signals"), *it;
	char p[JSON_PATH_MAX];
	size_t i = 0;
	int rc;

	if (!arr)
		return 0;
	if (!cJSON_IsArray(arr))
		return json_util_fail(err, errlen, "signals", "expected an array");
	cJSON_ArrayForEach(it, arr)
	{
		json_util_path_index(p, sizeof p, "signals", i++);
		if (dev->n_signals >= COSIM_SIGNAL_MAX)
			return json_util_fail(err, errlen, p, "more than %u signals",
					      COSIM_SIGNAL_MAX);
		if ((rc = parse_signal(it, p, dev, &dev->signals[dev->n_signals], err, errlen)))
			return rc;
		dev->n_signals++;
	}
	return 0;
}

static int parse_loopback(const cJSON *root, cosim_device *dev, char *err, size_t errlen)
{
	static const char *const keys[] = { "enabled", "pairs", "comment", NULL };
	static const char *const pair_keys[] = { "from", "to", "comment", NULL };
	const cJSON *l = json_util_get(root, "loopback"), *pairs, *it;
	char p[JSON_PATH_MAX], ip[JSON_PATH_MAX];
	size_t i = 0;
	int rc;
	const json_at at = { "loopback", err, errlen };
	const json_at at_ip = { ip, err, errlen };

	if (!l)
		return 0;
	if ((rc = json_util_check_object(l, &at, keys)) ||
	    (rc = json_util_opt_bool(l, "enabled", &at, &dev->loopback_enabled)))
		return rc;
	pairs = json_util_get(l, "pairs");
	if (!pairs)
		return 0;
	json_util_path_key(p, sizeof p, "loopback", "pairs");
	if (!cJSON_IsArray(pairs))
		return json_util_fail(err, errlen, p, "expected an array of {\"from\", \"to\"}");
	cJSON_ArrayForEach(it, pairs)
	{
		cosim_loopback_desc *d = &dev->loopback[dev->n_loopback];
		json_util_path_index(ip, sizeof ip, p, i++);
		if (dev->n_loopback >= COSIM_LOOPBACK_MAX)
			return json_util_fail(err, errlen, ip, "more than %u pairs",
					      COSIM_LOOPBACK_MAX);
		if ((rc = json_util_check_object(it, &at_ip, pair_keys)) ||
		    (rc = get_object(it, "from", ip, true, &d->from_index, &d->from_sub, err,
				     errlen)) ||
		    (rc = check_numeric(dev->od, d->from_index, d->from_sub, ip, "from", err,
					errlen)) ||
		    (rc = get_object(it, "to", ip, true, &d->to_index, &d->to_sub, err, errlen)) ||
		    (rc = check_numeric(dev->od, d->to_index, d->to_sub, ip, "to", err, errlen)))
			return rc;
		dev->n_loopback++;
	}
	return 0;
}

/* ---- node-relative COB-IDs ----------------------------------------------------- */

void cosim_device_rebase(cosim_device *dev, co_od *od, uint8_t node_id)
{
	for (unsigned i = 0; i < dev->n_rel; i++) {
		co_od_entry *e = co_od_find(od, dev->rel[i].index, dev->rel[i].sub);
		uint32_t v = dev->rel[i].base;
		if (!e)
			continue;
		if (node_id >= 1 && node_id <= 127)
			v += node_id;
		else
			v |= 0x80000000u; /* unconfigured: no COB-ID of its own */
		co_od_entry_set_default_raw(e, v);
		co_od_entry_set_raw(e, v);
	}
}

/* ---- loading ------------------------------------------------------------------- */

/* The factory image (docs/cosim.md "Program download"): the text
 * "cosim factory image <1008h> <100Ah>" and its CRC-32, little-endian, so
 * that it passes the same check as a downloaded image and 1F56h:1 is its
 * CRC like any running image's. */
static int factory_image(const co_od *od, uint8_t *img, size_t cap, uint32_t *len)
{
	char name[64] = "", version[64] = "";
	uint32_t name_len = 0, version_len = 0, crc;
	int text;

	if (co_od_get_bytes(od, 0x1008, 0, name, sizeof name - 1, &name_len) ||
	    co_od_get_bytes(od, 0x100A, 0, version, sizeof version - 1, &version_len))
		return -EMSGSIZE;
	name[name_len] = 0;
	version[version_len] = 0;
	text = snprintf((char *)img, cap, "cosim factory image %s %s", name, version);
	if (text < 0 || (size_t)text + 4 > cap)
		return -EMSGSIZE;
	crc = cosim_crc32(img, (size_t)text);
	for (int b = 0; b < 4; b++)
		img[text + b] = (uint8_t)(crc >> (8 * b));
	*len = (uint32_t)text + 4;
	return 0;
}

/* 1F50h:1 (the flash, holding image), 1F51h:1 and 1F56h:1. */
static int add_program_objects(cosim_device *dev, const uint8_t *image, uint32_t image_len,
			       char *err, size_t errlen)
{
	uint32_t flash = dev->program.flash_max;
	co_od_entry *e;
	int rc;

	if ((rc = co_od_ensure_num(dev->od, 0x1F50, 0, CO_T_UNSIGNED8, CO_ACC_RO, 1,
				   CO_OBJ_ARRAY)) ||
	    (rc = co_od_add_bytes(dev->od, 0x1F50, 1, CO_T_DOMAIN, CO_ACC_WO, flash, image,
				  image_len, &e)))
		return rc == -ENOMEM ? rc
				     : json_util_fail(err, errlen, "program", "cannot add 1F50h");
	e->obj_code = CO_OBJ_ARRAY;
	if ((rc = co_od_ensure_num(dev->od, 0x1F51, 0, CO_T_UNSIGNED8, CO_ACC_RO, 1,
				   CO_OBJ_ARRAY)) ||
	    (rc = co_od_ensure_num(dev->od, 0x1F51, 1, CO_T_UNSIGNED8, CO_ACC_RW,
				   image_len ? COSIM_PROG_RUNNING : COSIM_PROG_CLEARED,
				   CO_OBJ_ARRAY)) ||
	    (rc = co_od_ensure_num(dev->od, 0x1F56, 0, CO_T_UNSIGNED8, CO_ACC_RO, 1,
				   CO_OBJ_ARRAY)) ||
	    (rc = co_od_ensure_num(dev->od, 0x1F56, 1, CO_T_UNSIGNED32, CO_ACC_RO, 0,
				   CO_OBJ_ARRAY)))
		return rc == -ENOMEM
			       ? rc
			       : json_util_fail(err, errlen, "program", "cannot add 1F51h/1F56h");
	return 0;
}

/* "program": {"flash_max": N, "refuse": bool, "factory": bool} -> 1F50h:1
 * (DOMAIN wo, N bytes, the factory image or empty), 1F51h:1 (UNSIGNED8
 * rw), 1F56h:1 (UNSIGNED32 ro); the program module sets the power-on
 * state of the last two from the flash. */
static int parse_program(const cJSON *root, cosim_device *dev, char *err, size_t errlen)
{
	static const char *const keys[] = { "flash_max", "refuse", "factory", "comment", NULL };
	const cJSON *v = json_util_get(root, "program");
	uint64_t flash = 256u * 1024u;
	uint8_t image[160];
	uint32_t image_len = 0;
	int rc;
	const json_at at = { "program", err, errlen };

	if (!v)
		return 0;
	dev->program.factory = true;
	if ((rc = json_util_check_object(v, &at, keys)) ||
	    (rc = json_util_opt_uint(v, "flash_max", &at, 16, 16u * 1024u * 1024u, &flash)) ||
	    (rc = json_util_opt_bool(v, "refuse", &at, &dev->program.refuse)) ||
	    (rc = json_util_opt_bool(v, "factory", &at, &dev->program.factory)))
		return rc;
	if (co_od_has_index(dev->od, 0x1F50) || co_od_has_index(dev->od, 0x1F51) ||
	    co_od_has_index(dev->od, 0x1F56))
		return json_util_fail(err, errlen, "program",
				      "1F50h/1F51h/1F56h are defined already (in \"objects\")");
	if (dev->program.factory && factory_image(dev->od, image, sizeof image, &image_len))
		return json_util_fail(err, errlen, "program",
				      "1008h/100Ah are too long for the factory image (63 bytes "
				      "each at most)");
	if (image_len > flash)
		return json_util_fail(err, errlen, "program",
				      "flash_max %u is below the factory image's %u bytes",
				      (unsigned)flash, (unsigned)image_len);
	dev->program.enabled = true;
	dev->program.flash_max = (uint32_t)flash;
	return add_program_objects(dev, image_len ? image : NULL, image_len, err, errlen);
}

static int build(cosim_device *dev, const cJSON *root, const cosim_device_opts *opts, char *err,
		 size_t errlen)
{
	struct parsed_top t;
	const cJSON *v;
	int rc;

	if (!cJSON_IsObject(root))
		return json_util_fail(err, errlen, "(top)", "expected an object, got %s",
				      json_util_kind(root));
	if ((rc = parse_top(root, dev, opts, &t, err, errlen)))
		return rc;
	if ((rc = co_od_create(&dev->od, 256)))
		return rc;
	/* od_std wants a real node-ID: an unconfigured device is built as
	 * node 1 and its node-relative COB-IDs are then made invalid. */
	rc = co_od_add_std_comm(dev->od, dev->node_id == 255 ? 1 : dev->node_id, &t.std);
	if (rc == -ENOMEM)
		return rc;
	if (rc)
		return json_util_fail(err, errlen, "(top)",
				      "cannot build the standard objects (%s)", strerror(-rc));
	add_rel(dev, 0x1200, 1, 0x600);
	add_rel(dev, 0x1200, 2, 0x580);
	add_rel(dev, 0x1014, 0, 0x80);
	if ((v = json_util_get(root, "objects")) &&
	    (rc = json_od_add_objects(dev->od, v, "objects", err, errlen)))
		return rc;
	if ((rc = parse_pdos(root, dev, CO_PDO_TX, err, errlen)) ||
	    (rc = parse_pdos(root, dev, CO_PDO_RX, err, errlen)))
		return rc;
	/* Values last: they may set any object, standard or PDO ones too. */
	if ((v = json_util_get(root, "values")) &&
	    (rc = json_od_apply_values(dev->od, v, "values", err, errlen)))
		return rc;
	if ((rc = parse_lss(root, dev, err, errlen)) ||
	    (rc = parse_program(root, dev, err, errlen)) ||
	    (rc = parse_signals(root, dev, err, errlen)) ||
	    (rc = parse_loopback(root, dev, err, errlen)))
		return rc;
	if (dev->node_id == 255) {
		if (!dev->lss_enabled)
			return json_util_fail(
				err, errlen, "node_id",
				"255 (unconfigured) needs \"lss\": {\"enabled\": true}");
		cosim_device_rebase(dev, dev->od, 255);
	}
	return 0;
}

int cosim_device_load_string(cosim_device *dev, const char *file, const char *json,
			     const cosim_device_opts *opts, char *err, size_t errlen)
{
	char msg[COSIM_ERR_MAX];
	cJSON *root = NULL;
	int rc;

	memset(dev, 0, sizeof *dev);
	snprintf(dev->file, sizeof dev->file, "%s", file);
	msg[0] = 0;
	rc = json_util_parse(json, &root, msg, sizeof msg);
	if (!rc)
		rc = build(dev, root, opts, msg, sizeof msg);
	cJSON_Delete(root);
	if (rc) {
		if (rc == -ENOMEM)
			snprintf(err, errlen, "%s: out of memory", file);
		else
			snprintf(err, errlen, "%s: %s", file, msg);
		cosim_device_free(dev);
	}
	return rc;
}

int cosim_device_load(cosim_device *dev, const char *path, const cosim_device_opts *opts, char *err,
		      size_t errlen)
{
	FILE *f = fopen(path, "rb");
	char *text;
	long n;
	int rc;

	if (!f) {
		rc = -errno;
		snprintf(err, errlen, "%s: cannot open: %s", path, strerror(errno));
		return rc;
	}
	if (fseek(f, 0, SEEK_END) < 0 || (n = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) < 0 ||
	    n > 4 * 1024 * 1024) {
		fclose(f);
		snprintf(err, errlen, "%s: cannot read (not a regular file, or above 4 MiB)", path);
		return -EIO;
	}
	text = malloc((size_t)n + 1);
	if (!text) {
		fclose(f);
		return -ENOMEM;
	}
	if (fread(text, 1, (size_t)n, f) != (size_t)n) {
		fclose(f);
		free(text);
		snprintf(err, errlen, "%s: read error", path);
		return -EIO;
	}
	fclose(f);
	text[n] = 0;
	rc = cosim_device_load_string(dev, path, text, opts, err, errlen);
	free(text);
	return rc;
}

void cosim_device_free(cosim_device *dev)
{
	if (!dev)
		return;
	co_od_destroy(dev->od);
	dev->od = NULL;
}
