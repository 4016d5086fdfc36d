/* Proof that POSIX message queues work where the integration tests run (natively or
 * in the VM): create, send, receive in priority order, non-blocking full/empty
 * behaviour, epoll readiness, unlink. The mailbox is built on exactly these calls. */
#include <errno.h>
#include <fcntl.h>
#include <mqueue.h>
#include <stdio.h>
#include <string.h>
#include <sys/epoll.h>
#include <unistd.h>

#include "unity.h"

static char name[64];
static mqd_t q = (mqd_t)-1;

void setUp(void)
{
	snprintf(name, sizeof name, "/cogw-test-mq-%d", (int)getpid());
	struct mq_attr attr = { .mq_maxmsg = 8, .mq_msgsize = 256 };
	q = mq_open(name, O_CREAT | O_EXCL | O_RDWR | O_NONBLOCK, 0600, &attr);
	TEST_ASSERT_TRUE_MESSAGE(q != (mqd_t)-1, strerror(errno));
}

void tearDown(void)
{
	if (q != (mqd_t)-1)
		mq_close(q);
	mq_unlink(name);
}

static void test_attributes_are_what_we_asked_for(void)
{
	struct mq_attr attr;
	TEST_ASSERT_EQUAL_INT(0, mq_getattr(q, &attr));
	TEST_ASSERT_EQUAL_INT(8, attr.mq_maxmsg);
	TEST_ASSERT_EQUAL_INT(256, attr.mq_msgsize);
	TEST_ASSERT_EQUAL_INT(0, attr.mq_curmsgs);
}

static void test_send_receive_in_priority_order(void)
{
	TEST_ASSERT_EQUAL_INT(0, mq_send(q, "low", 4, 1));
	TEST_ASSERT_EQUAL_INT(0, mq_send(q, "high", 5, 7));
	char buf[256];
	unsigned prio = 0;
	TEST_ASSERT_EQUAL_INT(5, (int)mq_receive(q, buf, sizeof buf, &prio));
	TEST_ASSERT_EQUAL_STRING("high", buf);
	TEST_ASSERT_EQUAL_UINT(7, prio);
	TEST_ASSERT_EQUAL_INT(4, (int)mq_receive(q, buf, sizeof buf, &prio));
	TEST_ASSERT_EQUAL_STRING("low", buf);
}

static void test_full_and_empty_queue_do_not_block(void)
{
	char msg[256] = { 0 };
	for (int i = 0; i < 8; i++)
		TEST_ASSERT_EQUAL_INT(0, mq_send(q, msg, sizeof msg, 0));
	TEST_ASSERT_EQUAL_INT(-1, mq_send(q, msg, sizeof msg, 0));
	TEST_ASSERT_EQUAL_INT(EAGAIN, errno);
	for (int i = 0; i < 8; i++)
		TEST_ASSERT_EQUAL_INT(256, (int)mq_receive(q, msg, sizeof msg, NULL));
	TEST_ASSERT_EQUAL_INT(-1, (int)mq_receive(q, msg, sizeof msg, NULL));
	TEST_ASSERT_EQUAL_INT(EAGAIN, errno);
}

static void test_oversized_message_is_refused(void)
{
	char msg[300] = { 0 };
	TEST_ASSERT_EQUAL_INT(-1, mq_send(q, msg, sizeof msg, 0));
	TEST_ASSERT_EQUAL_INT(EMSGSIZE, errno);
}

static void test_queue_is_an_epoll_descriptor(void)
{
	int ep = epoll_create1(EPOLL_CLOEXEC);
	TEST_ASSERT_TRUE(ep >= 0);
	struct epoll_event ev = { .events = EPOLLIN, .data.u32 = 42 };
	TEST_ASSERT_EQUAL_INT(0, epoll_ctl(ep, EPOLL_CTL_ADD, (int)q, &ev));
	struct epoll_event out;
	TEST_ASSERT_EQUAL_INT(0, epoll_wait(ep, &out, 1, 0));
	TEST_ASSERT_EQUAL_INT(0, mq_send(q, "x", 1, 0));
	TEST_ASSERT_EQUAL_INT(1, epoll_wait(ep, &out, 1, 1000));
	TEST_ASSERT_EQUAL_UINT32(42, out.data.u32);
	close(ep);
}

static void test_unlink_removes_the_name(void)
{
	TEST_ASSERT_EQUAL_INT(0, mq_unlink(name));
	TEST_ASSERT_TRUE(mq_open(name, O_RDONLY) == (mqd_t)-1);
	TEST_ASSERT_EQUAL_INT(ENOENT, errno);
	/* the open descriptor still works until closed */
	TEST_ASSERT_EQUAL_INT(0, mq_send(q, "y", 1, 0));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_attributes_are_what_we_asked_for);
	RUN_TEST(test_send_receive_in_priority_order);
	RUN_TEST(test_full_and_empty_queue_do_not_block);
	RUN_TEST(test_oversized_message_is_refused);
	RUN_TEST(test_queue_is_an_epoll_descriptor);
	RUN_TEST(test_unlink_removes_the_name);
	return UNITY_END();
}
