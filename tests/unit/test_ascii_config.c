/* SPDX-License-Identifier: MIT */
/*
 * tests/unit/test_ascii_config.c - cogw-ascii's configuration loader
 * (apps/cogw-ascii/ascii_config.c): the defaults, every key taken, and
 * each class of bad input refused with "source: path: reason"
 * (docs/ascii.md "Configuration").
 */
#include "unity.h"

#include <errno.h>
#include <string.h>

#include "apps/cogw-ascii/ascii_config.h"
#include "apps/common/config.h"

void setUp(void) {}

void tearDown(void) {}

static ascii_config c;
static char err[512];

static int load(const char *json)
{
	err[0] = '\0';
	return ascii_config_load_string(&c, json, "a.json", err, sizeof err);
}

static void test_defaults(void)
{
	TEST_ASSERT_EQUAL_INT(0, load("{}"));
	TEST_ASSERT_EQUAL_STRING("/run/cogw/ascii.sock", c.unix_socket);
	TEST_ASSERT_EQUAL_UINT(0660, c.unix_mode);
	TEST_ASSERT_FALSE(c.tcp);
	TEST_ASSERT_EQUAL_STRING("127.0.0.1", c.tcp_address);
	TEST_ASSERT_EQUAL_UINT8(COGW_ACCESS_READ, c.tcp_access);
	TEST_ASSERT_EQUAL_UINT(64, c.max_connections);
	TEST_ASSERT_EQUAL_UINT(65536, c.max_line);
	TEST_ASSERT_EQUAL_UINT(4, c.max_outstanding);
	TEST_ASSERT_EQUAL_INT(-1, c.default_network);
	TEST_ASSERT_FALSE(c.sdo_block);
}

static void test_every_key(void)
{
	TEST_ASSERT_EQUAL_INT_MESSAGE(
		0,
		load("{\"version\": 1, \"comment\": \"x\", \"daemon_config\": "
		     "\"/etc/cogw/cogw.json\","
		     " \"unix_socket\": \"\", \"unix_mode\": \"0600\", \"route_line\": 2,"
		     " \"tcp\": {\"address\": \"::1\", \"port\": 5000, \"access\": \"write\"},"
		     " \"limits\": {\"max_connections\": 3, \"max_line\": 100, "
		     "\"max_outstanding\": 2,"
		     " \"max_output\": 5000, \"request_timeout_ms\": 200},"
		     " \"session\": {\"network\": 0, \"sdo_timeout_ms\": 20, \"sdo_block\": "
		     "true}}"),
		err);
	TEST_ASSERT_EQUAL_STRING("/etc/cogw/cogw.json", c.daemon_config);
	TEST_ASSERT_EQUAL_STRING("", c.unix_socket);
	TEST_ASSERT_EQUAL_UINT(0600, c.unix_mode);
	TEST_ASSERT_EQUAL_UINT(2, c.route_line);
	TEST_ASSERT_TRUE(c.tcp);
	TEST_ASSERT_EQUAL_STRING("::1", c.tcp_address);
	TEST_ASSERT_EQUAL_UINT16(5000, c.tcp_port);
	TEST_ASSERT_EQUAL_UINT8(COGW_ACCESS_WRITE, c.tcp_access);
	TEST_ASSERT_EQUAL_UINT(3, c.max_connections);
	TEST_ASSERT_EQUAL_UINT(100, c.max_line);
	TEST_ASSERT_EQUAL_UINT(2, c.max_outstanding);
	TEST_ASSERT_EQUAL_UINT(5000, c.max_output);
	TEST_ASSERT_EQUAL_UINT(200, c.request_timeout_ms);
	TEST_ASSERT_EQUAL_INT(0, c.default_network);
	TEST_ASSERT_EQUAL_UINT(20, c.sdo_timeout_ms);
	TEST_ASSERT_TRUE(c.sdo_block);
}

static void test_bad_input_refused_with_its_path(void)
{
	static const struct {
		const char *json, *msg;
	} bad[] = {
		{ "{", "a.json: line 1 column" },
		{ "[]", "a.json: (top): must be an object" },
		{ "{\"versoin\": 1}", "a.json: versoin: unknown key (did you mean \"version\"?)" },
		{ "{\"version\": 2}", "a.json: version:" },
		{ "{\"unix_mode\": \"0666\"}", "a.json: unix_mode: 0666 lets every local user" },
		{ "{\"unix_mode\": 432}", "a.json: unix_mode: must be an octal string" },
		{ "{\"tcp\": {\"address\": \"localhost\"}}",
		  "a.json: tcp.address: \"localhost\" is not" },
		{ "{\"tcp\": {\"port\": 0}}", "a.json: tcp.port:" },
		{ "{\"tcp\": {\"access\": \"admin\"}}",
		  "a.json: tcp.access: \"admin\" is not one of" },
		{ "{\"tcp\": true}", "a.json: tcp: must be an object" },
		{ "{\"limits\": {\"max_connections\": 0}}", "a.json: limits.max_connections:" },
		{ "{\"limits\": {\"max_line\": 63}}", "a.json: limits.max_line:" },
		{ "{\"limits\": {\"max_outstanding\": 65}}", "a.json: limits.max_outstanding:" },
		{ "{\"limits\": {\"max_output\": 100}}", "a.json: limits.max_output:" },
		{ "{\"limits\": {\"max_lin\": 100}}", "a.json: limits.max_lin: unknown key" },
		{ "{\"session\": {\"network\": 128}}", "a.json: session.network:" },
		{ "{\"session\": {\"sdo_block\": 1}}", "a.json: session.sdo_block:" },
		{ "{\"route_line\": 16}", "a.json: route_line:" },
		{ "{\"version\": 1, \"version\": 1}", "a.json: version: duplicate key" },
	};

	for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
		TEST_ASSERT_EQUAL_INT_MESSAGE(-EINVAL, load(bad[i].json), bad[i].json);
		TEST_ASSERT_EQUAL_STRING_LEN_MESSAGE(bad[i].msg, err, strlen(bad[i].msg), err);
	}
}

static void test_missing_file(void)
{
	TEST_ASSERT_EQUAL_INT(-ENOENT,
			      ascii_config_load_file(&c, "/nonexistent/a.json", err, sizeof err));
	TEST_ASSERT_NOT_NULL(strstr(err, "/nonexistent/a.json: cannot open"));
	TEST_ASSERT_EQUAL_INT(0, ascii_config_load_file(&c, NULL, err, sizeof err));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_defaults);
	RUN_TEST(test_every_key);
	RUN_TEST(test_bad_input_refused_with_its_path);
	RUN_TEST(test_missing_file);
	return UNITY_END();
}
