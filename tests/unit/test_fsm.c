/* SPDX-License-Identifier: MIT */
/*
 * The state-machine shape (core/fsm.h): enter chains, leave order, stay,
 * inputs to a state without a handler, state names.
 */
#include <string.h>

#include "unity.h"

#include "core/fsm.h"

enum {
	S_IDLE,
	S_WAIT,
	S_PASS,
	S_DONE,
	S_COUNT
};

typedef struct trace {
	char log[128];
	int timeouts;
} trace;

static void note(trace *t, const char *what)
{
	strncat(t->log, what, sizeof(t->log) - strlen(t->log) - 1);
}

static int idle_frame(void *obj, const co_frame *f, uint64_t now_us)
{
	(void)now_us;
	note(obj, "f");
	return f->data[0] == 1 ? S_WAIT : CO_FSM_STAY;
}
static void idle_leave(void *obj, uint64_t now_us)
{
	(void)now_us;
	note(obj, "<I");
}
static int wait_enter(void *obj, uint64_t now_us)
{
	(void)now_us;
	note(obj, ">W");
	return CO_FSM_STAY;
}
static int wait_timeout(void *obj, uint64_t now_us)
{
	(void)now_us;
	trace *t = obj;
	return ++t->timeouts >= 2 ? S_PASS : CO_FSM_STAY;
}
static void wait_leave(void *obj, uint64_t now_us)
{
	(void)now_us;
	note(obj, "<W");
}
static int pass_enter(void *obj, uint64_t now_us)
{
	(void)now_us;
	note(obj, ">P");
	return S_DONE; /* chains straight on */
}
static int done_enter(void *obj, uint64_t now_us)
{
	(void)now_us;
	note(obj, ">D");
	return CO_FSM_STAY;
}
static int done_con(void *obj, const void *con, uint64_t now_us)
{
	(void)now_us;
	note(obj, con);
	return S_IDLE;
}

static const co_fsm_state states[S_COUNT] = {
	[S_IDLE] = { .name = "idle", .on_frame = idle_frame, .on_leave = idle_leave },
	[S_WAIT] = { .name = "wait",
		     .on_enter = wait_enter,
		     .on_timeout = wait_timeout,
		     .on_leave = wait_leave },
	[S_PASS] = { .name = "pass", .on_enter = pass_enter },
	[S_DONE] = { .name = "done", .on_enter = done_enter, .on_con = done_con },
};
static const co_fsm_def def = { "test", states, S_COUNT };

static trace t;
static co_fsm m;

void setUp(void)
{
	memset(&t, 0, sizeof(t));
	co_fsm_init(&m, &def, &t, S_IDLE);
}
void tearDown(void) {}

static void test_init_calls_no_handler(void)
{
	TEST_ASSERT_EQUAL(S_IDLE, co_fsm_state_of(&m));
	TEST_ASSERT_EQUAL_STRING("", t.log);
}

static void test_frame_stays_or_moves(void)
{
	co_frame f = { .id = 0x581, .len = 1, .data = { 0 } };
	co_fsm_frame(&m, &f, 0);
	TEST_ASSERT_EQUAL(S_IDLE, co_fsm_state_of(&m));
	f.data[0] = 1;
	co_fsm_frame(&m, &f, 0);
	TEST_ASSERT_EQUAL(S_WAIT, co_fsm_state_of(&m));
	TEST_ASSERT_EQUAL_STRING("ff<I>W", t.log);
}

static void test_enter_chain_and_leave_order(void)
{
	co_fsm_goto(&m, S_WAIT, 0);
	co_fsm_timeout(&m, 1);
	TEST_ASSERT_EQUAL(S_WAIT, co_fsm_state_of(&m));
	co_fsm_timeout(&m, 2);
	TEST_ASSERT_EQUAL(S_DONE, co_fsm_state_of(&m));
	TEST_ASSERT_EQUAL_STRING("<I>W<W>P>D", t.log);
}

static void test_missing_handler_ignores_input(void)
{
	co_fsm_timeout(&m, 0);  /* idle has no on_timeout */
	co_fsm_con(&m, "x", 0); /* nor on_con */
	TEST_ASSERT_EQUAL(S_IDLE, co_fsm_state_of(&m));
	TEST_ASSERT_EQUAL_STRING("", t.log);
}

static void test_con_reaches_state(void)
{
	co_fsm_goto(&m, S_PASS, 0);
	co_fsm_con(&m, "c", 0);
	TEST_ASSERT_EQUAL(S_IDLE, co_fsm_state_of(&m));
	TEST_ASSERT_EQUAL_STRING("<I>P>Dc", t.log);
}

static void test_names(void)
{
	TEST_ASSERT_EQUAL_STRING("wait", co_fsm_state_name(&def, S_WAIT));
	TEST_ASSERT_EQUAL_STRING("?", co_fsm_state_name(&def, S_COUNT));
	TEST_ASSERT_EQUAL_STRING("?", co_fsm_state_name(&def, -1));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_init_calls_no_handler);
	RUN_TEST(test_frame_stays_or_moves);
	RUN_TEST(test_enter_chain_and_leave_order);
	RUN_TEST(test_missing_handler_ignores_input);
	RUN_TEST(test_con_reaches_state);
	RUN_TEST(test_names);
	return UNITY_END();
}
