/* SPDX-License-Identifier: MIT */
/* A line's "app" (docs/config.md): the application watchdog's
 * configured reactions, host not ready's NMT action and the safe outputs,
 * checked against the line's object dictionary; every bad input refused
 * with its path. */
#include <errno.h>
#include <string.h>

#include "apps/common/config.h"
#include "core/appwd.h"
#include "core/nmt.h"
#include "unity.h"

static cogw_config cfg;
static char err[512];

void setUp(void)
{
	memset(&cfg, 0, sizeof(cfg));
	err[0] = '\0';
}

void tearDown(void)
{
	cogw_config_free(&cfg);
}

#define OBJECTS                                                                                   \
	", \"objects\": [{\"index\": \"0x2000\", \"type\": \"UNSIGNED16\", \"access\": \"rwr\", " \
	"\"default\": 500, \"max\": 1000}, {\"index\": \"0x2001\", \"type\": \"INTEGER8\"}]"
#define CFG_APP(app)                                                                          \
	"{\"lines\": [{\"interface\": \"vcan0\", \"bitrate\": 500000, \"node_id\": 5" OBJECTS \
	", \"app\": " app "}]}"

static void expect_error(const char *json, const char *msg)
{
	TEST_ASSERT_EQUAL_INT(-EINVAL,
			      cogw_config_load_string(&cfg, json, "t.json", err, sizeof(err)));
	TEST_ASSERT_EQUAL_STRING(msg, err);
}

static void test_absent_defaults(void)
{
	TEST_ASSERT_EQUAL_INT(
		0, cogw_config_load_string(&cfg, CFG_APP("{}"), "t.json", err, sizeof(err)));
	TEST_ASSERT_EQUAL_UINT32(0, cfg.lines[0].appwd.reactions);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_CS_STOP, cfg.lines[0].appwd.not_ready_cs);
	TEST_ASSERT_EQUAL_UINT8(0, cfg.lines[0].appwd.n_safe_outputs);
}

static void test_full_section(void)
{
	const cogw_appwd_config *a;

	TEST_ASSERT_EQUAL_INT(
		0, cogw_config_load_string(
			   &cfg,
			   CFG_APP("{\"watchdog_reactions\": [\"emcy\", \"nmt-stop\", "
				   "\"safe-outputs\"], \"not_ready_nmt\": \"pre-operational\", "
				   "\"safe_outputs\": [{\"index\": \"0x2000\", \"value\": 0}, "
				   "{\"index\": 8193, \"sub\": 0, \"value\": -5}]}"),
			   "t.json", err, sizeof(err)));
	TEST_ASSERT_EQUAL_STRING("", err);
	a = &cfg.lines[0].appwd;
	TEST_ASSERT_EQUAL_HEX32(CO_APPWD_EMCY | CO_APPWD_NMT_STOP | CO_APPWD_SAFE_OUTPUTS,
				a->reactions);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_CS_ENTER_PREOP, a->not_ready_cs);
	TEST_ASSERT_EQUAL_UINT8(2, a->n_safe_outputs);
	TEST_ASSERT_EQUAL_HEX16(0x2000, a->safe_outputs[0].index);
	TEST_ASSERT_EQUAL_UINT8(2, a->safe_outputs[0].len);
	TEST_ASSERT_EQUAL_HEX8(0, a->safe_outputs[0].value[0]);
	TEST_ASSERT_EQUAL_UINT8(1, a->safe_outputs[1].len);
	TEST_ASSERT_EQUAL_HEX8(0xFB, a->safe_outputs[1].value[0]);
}

static void test_bad_input(void)
{
	expect_error(CFG_APP("{\"watchdog_reactions\": [\"emcy\", \"explode\"]}"),
		     "t.json: lines[0].app.watchdog_reactions: [1]: not a reaction "
		     "(emcy, nmt-preop, nmt-stop, nmt-reset-comm, nmt-reset-node, hb-stop, "
		     "safe-outputs)");
	expect_error(CFG_APP("{\"watchdog_reactions\": []}"),
		     "t.json: lines[0].app.watchdog_reactions: must be a non-empty array "
		     "of reaction names");
	expect_error(CFG_APP("{\"watchdog_reactions\": [\"nmt-stop\", \"nmt-preop\"]}"),
		     "t.json: lines[0].app.watchdog_reactions: at most one NMT reaction");
	expect_error(CFG_APP("{\"watchdog_reactions\": [\"safe-outputs\"]}"),
		     "t.json: lines[0].app.watchdog_reactions: safe-outputs needs "
		     "\"safe_outputs\"");
	expect_error(CFG_APP("{\"not_ready_nmt\": \"reset\"}"),
		     "t.json: lines[0].app.not_ready_nmt: must be \"stop\" or "
		     "\"pre-operational\"");
	expect_error(CFG_APP("{\"safe_outputs\": [{\"index\": \"0x1017\", \"value\": 0}]}"),
		     "t.json: lines[0].app.safe_outputs[0].index: 1017h is a "
		     "communication object, not an output");
	expect_error(CFG_APP("{\"safe_outputs\": [{\"index\": \"0x2002\", \"value\": 0}]}"),
		     "t.json: lines[0].app.safe_outputs[0].index: 2002h:00 is not an "
		     "object of this line");
	expect_error(CFG_APP("{\"safe_outputs\": [{\"index\": \"0x2000\", \"value\": 0}, "
			     "{\"index\": \"0x2000\", \"value\": 1}]}"),
		     "t.json: lines[0].app.safe_outputs[1].index: 2000h:00 is named "
		     "twice");
	expect_error(CFG_APP("{\"safe_outputs\": [{\"index\": \"0x2000\", \"value\": 1001}]}"),
		     "t.json: lines[0].app.safe_outputs[0].value: not a valid value of "
		     "2000h:00");
	expect_error(CFG_APP("{\"safe_outputs\": [{\"index\": \"0x2000\", \"value\": \"x\"}]}"),
		     "t.json: lines[0].app.safe_outputs[0].value: \"x\" is not an "
		     "integer");
	expect_error(CFG_APP("{\"safe_outputs\": [{\"index\": \"0x2000\", \"value\": 0, "
			     "\"when\": 1}]}"),
		     "t.json: lines[0].app.safe_outputs[0].when: unknown key");
	expect_error(CFG_APP("{\"hold\": true}"), "t.json: lines[0].app.hold: unknown key");
}

/* One "app" block carries both the objects clients own and the watchdog's
 * keys: each reader takes its own, neither refuses the other's. */
static void test_shared_with_owned_objects(void)
{
	TEST_ASSERT_EQUAL_INT(
		0,
		cogw_config_load_string(
			&cfg,
			CFG_APP("{\"max_created\": 5, \"objects\": [{\"index\": \"0x2001\", "
				"\"kind\": \"held\", \"uid\": 0}], \"not_ready_nmt\": "
				"\"pre-operational\", \"safe_outputs\": [{\"index\": \"0x2000\", "
				"\"value\": 1}]}"),
			"t.json", err, sizeof(err)));
	TEST_ASSERT_EQUAL_STRING("", err);
	TEST_ASSERT_EQUAL_UINT16(5, cfg.lines[0].app.max_created);
	TEST_ASSERT_EQUAL_UINT16(1, cfg.lines[0].app.n_decl);
	TEST_ASSERT_EQUAL_HEX16(0x2001, cfg.lines[0].app.decl[0].index);
	TEST_ASSERT_EQUAL_HEX8(CO_NMT_CS_ENTER_PREOP, cfg.lines[0].appwd.not_ready_cs);
	TEST_ASSERT_EQUAL_UINT8(1, cfg.lines[0].appwd.n_safe_outputs);
	/* a served object is no output: its value is never read from the OD */
	cogw_config_free(&cfg);
	memset(&cfg, 0, sizeof(cfg));
	expect_error(CFG_APP("{\"objects\": [{\"index\": \"0x2001\", \"kind\": \"served\", "
			     "\"uid\": 0}], \"safe_outputs\": [{\"index\": \"0x2001\", "
			     "\"value\": 0}]}"),
		     "t.json: lines[0].app.safe_outputs[0].index: 2001h:00 is served by a client, "
		     "not an output");
	/* an error after the owned objects still names the watchdog's key */
	cogw_config_free(&cfg);
	memset(&cfg, 0, sizeof(cfg));
	expect_error(CFG_APP("{\"objects\": [{\"index\": \"0x2001\", \"kind\": \"held\", "
			     "\"uid\": 0}], \"not_ready_nmt\": \"off\"}"),
		     "t.json: lines[0].app.not_ready_nmt: must be \"stop\" or "
		     "\"pre-operational\"");
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_absent_defaults);
	RUN_TEST(test_full_section);
	RUN_TEST(test_bad_input);
	RUN_TEST(test_shared_with_owned_objects);
	return UNITY_END();
}
