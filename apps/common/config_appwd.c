/* SPDX-License-Identifier: MIT */
/*
 * apps/common/config_appwd.c - the application watchdog's keys of a line's
 * "app": its configured reactions, the NMT action of host not ready and
 * the safe outputs (docs/config.md "The application", docs/application.md).
 * Read after the line's object dictionary is built: a safe output names
 * one of its objects and its value is encoded by that object's type.
 */
#include "apps/common/config_read.h"

#include <string.h>

#include "apps/common/json_od.h"
#include "apps/common/json_util.h"
#include "core/appwd.h"
#include "core/nmt.h"
#include "mailbox/proto.h"

static const char *const safe_keys[] = { "index", "sub", "value", "comment", NULL };

static int parse_reactions(struct ctx *c, const cJSON *v, const char *path, uint32_t *out)
{
	const cJSON *it;
	uint32_t set = 0, bit;
	size_t i = 0;

	if (!cJSON_IsArray(v) || !cJSON_GetArraySize(v))
		return cfg_fail(c, path, "must be a non-empty array of reaction names");
	cJSON_ArrayForEach(it, v)
	{
		if (!cJSON_IsString(it) || mbx_appwd_reactions_parse(it->valuestring, &bit) < 0 ||
		    (bit & (bit - 1u)))
			return cfg_fail(c, path,
					"[%zu]: not a reaction (emcy, nmt-preop, nmt-stop, "
					"nmt-reset-comm, nmt-reset-node, hb-stop, safe-outputs)",
					i);
		set |= bit;
		i++;
	}
	if (!co_appwd_reactions_valid(set))
		return cfg_fail(c, path, "at most one NMT reaction");
	*out = set;
	return 0;
}

static int parse_not_ready(struct ctx *c, const cJSON *v, const char *path, uint8_t *cs)
{
	if (cJSON_IsString(v) && !strcmp(v->valuestring, "stop"))
		*cs = CO_NMT_CS_STOP;
	else if (cJSON_IsString(v) && !strcmp(v->valuestring, "pre-operational"))
		*cs = CO_NMT_CS_ENTER_PREOP;
	else
		return cfg_fail(c, path, "must be \"stop\" or \"pre-operational\"");
	return 0;
}

/* One safe output: an application object of the line (not 1000h..1FFFh),
 * at most 8 bytes, its value valid for it, named once. */
/* A served object's value is its owner's and never read from the OD: a
 * safe value written there would reach nobody (docs/application.md). */
static bool is_served(const cogw_app_config *app, uint16_t index, uint8_t sub)
{
	for (uint16_t i = 0; i < app->n_decl; i++)
		if (app->decl[i].index == index && app->decl[i].sub == sub)
			return app->decl[i].kind == MBX_APP_SERVED;
	return false;
}

static int parse_safe_output(struct ctx *c, const cJSON *o, const char *path,
			     const cogw_line_config *l, cogw_appwd_config *a)
{
	co_safe_output *s = &a->safe_outputs[a->n_safe_outputs];
	json_od_buf buf = { .buf = s->value, .cap = sizeof s->value };
	char p[JSON_PATH_MAX];
	co_od_entry *e;
	int rc;

	if ((rc = cfg_check_object(c, o, path, safe_keys)))
		return rc;
	json_util_path_key(p, sizeof p, path, "index");
	if ((rc = json_od_parse_index(json_util_get(o, "index"), p, &s->index, c->msg,
				      sizeof c->msg)))
		return rc;
	if ((rc = cfg_opt_u8(c, o, "sub", path, (cfg_range){ 0, 254 }, &s->sub)))
		return rc;
	if (s->index < 0x2000)
		return cfg_fail(c, p, "%04Xh is a communication object, not an output", s->index);
	if (!(e = co_od_find(l->od, s->index, s->sub)))
		return cfg_fail(c, p, "%04Xh:%02X is not an object of this line", s->index, s->sub);
	if (is_served(&l->app, s->index, s->sub))
		return cfg_fail(c, p, "%04Xh:%02X is served by a client, not an output", s->index,
				s->sub);
	for (unsigned i = 0; i < a->n_safe_outputs; i++)
		if (a->safe_outputs[i].index == s->index && a->safe_outputs[i].sub == s->sub)
			return cfg_fail(c, p, "%04Xh:%02X is named twice", s->index, s->sub);
	json_util_path_key(p, sizeof p, path, "value");
	if ((rc = json_od_parse_value(json_util_get(o, "value"), e->type, p, &buf, c->msg,
				      sizeof c->msg)))
		return rc;
	if (!buf.len || co_od_check_value(e, s->value, buf.len))
		return cfg_fail(c, p, "not a valid value of %04Xh:%02X", s->index, s->sub);
	s->len = (uint8_t)buf.len;
	a->n_safe_outputs++;
	return 0;
}

static int parse_safe_outputs(struct ctx *c, const cJSON *v, const char *path,
			      const cogw_line_config *l, cogw_appwd_config *a)
{
	char p[JSON_PATH_MAX];
	const cJSON *it;
	size_t i = 0;
	int rc;

	if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) > (int)COGW_SAFE_OUTPUTS_MAX)
		return cfg_fail(c, path, "must be an array of at most %u objects",
				COGW_SAFE_OUTPUTS_MAX);
	cJSON_ArrayForEach(it, v)
	{
		json_util_path_index(p, sizeof p, path, i++);
		if ((rc = parse_safe_output(c, it, p, l, a)))
			return rc;
	}
	return 0;
}

int cfg_parse_appwd(struct ctx *c, const cJSON *o, const char *path, cogw_line_config *l)
{
	cogw_appwd_config *a = &l->appwd;
	char p[JSON_PATH_MAX];
	const cJSON *v;
	int rc;

	if ((v = json_util_get(o, "safe_outputs"))) {
		json_util_path_key(p, sizeof p, path, "safe_outputs");
		if ((rc = parse_safe_outputs(c, v, p, l, a)))
			return rc;
	}
	if ((v = json_util_get(o, "not_ready_nmt"))) {
		json_util_path_key(p, sizeof p, path, "not_ready_nmt");
		if ((rc = parse_not_ready(c, v, p, &a->not_ready_cs)))
			return rc;
	}
	if ((v = json_util_get(o, "watchdog_reactions"))) {
		json_util_path_key(p, sizeof p, path, "watchdog_reactions");
		if ((rc = parse_reactions(c, v, p, &a->reactions)))
			return rc;
		if ((a->reactions & CO_APPWD_SAFE_OUTPUTS) && !a->n_safe_outputs)
			return cfg_fail(c, p, "safe-outputs needs \"safe_outputs\"");
	}
	return 0;
}
