/* Proof that the vcan lines are real SocketCAN: classic frames (11/29-bit, DLC 0-8,
 * RTR) go out on one line and arrive on that line only, with kernel receive
 * timestamps; error-frame reception can be enabled. Runs on vcan0..vcan2, which
 * tests/vcan/run provides (natively or inside the VM). */
#include <errno.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "unity.h"

#define LINE_COUNT 3

static int tx_sock[LINE_COUNT];
static int rx_sock[LINE_COUNT];

static int can_open(const char *ifname)
{
	int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
	TEST_ASSERT_TRUE_MESSAGE(fd >= 0, "socket(PF_CAN) failed: kernel without CAN?");
	struct sockaddr_can addr = { .can_family = AF_CAN,
				     .can_ifindex = (int)if_nametoindex(ifname) };
	TEST_ASSERT_NOT_EQUAL_MESSAGE(0, addr.can_ifindex,
				      "vcan interface missing: run under tests/vcan/run -n 3");
	TEST_ASSERT_EQUAL_INT(0, bind(fd, (struct sockaddr *)&addr, sizeof addr));
	int on = 1;
	TEST_ASSERT_EQUAL_INT(0, setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on));
	return fd;
}

void setUp(void)
{
	for (int i = 0; i < LINE_COUNT; i++) {
		char name[IFNAMSIZ];
		snprintf(name, sizeof name, "vcan%d", i);
		tx_sock[i] = can_open(name);
		rx_sock[i] = can_open(name);
	}
}

void tearDown(void)
{
	for (int i = 0; i < LINE_COUNT; i++) {
		close(tx_sock[i]);
		close(rx_sock[i]);
	}
}

static int readable_within(int fd, int timeout_ms)
{
	struct pollfd p = { .fd = fd, .events = POLLIN };
	return poll(&p, 1, timeout_ms);
}

/* Receives one frame and its kernel timestamp (CLOCK_REALTIME, SCM_TIMESTAMPNS). */
static void recv_with_timestamp(int fd, struct can_frame *frame, struct timespec *stamp)
{
	TEST_ASSERT_EQUAL_INT_MESSAGE(1, readable_within(fd, 2000), "no frame within 2 s");
	char control[CMSG_SPACE(sizeof(struct timespec))];
	struct iovec iov = { .iov_base = frame, .iov_len = sizeof *frame };
	struct msghdr msg = { .msg_iov = &iov,
			      .msg_iovlen = 1,
			      .msg_control = control,
			      .msg_controllen = sizeof control };
	TEST_ASSERT_EQUAL_INT((int)sizeof *frame, (int)recvmsg(fd, &msg, 0));
	memset(stamp, 0, sizeof *stamp);
	for (struct cmsghdr *c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c))
		if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS)
			memcpy(stamp, CMSG_DATA(c), sizeof *stamp);
}

static void assert_only_line_receives(int line, const struct can_frame *sent)
{
	struct timespec before, stamp;
	clock_gettime(CLOCK_REALTIME, &before);
	TEST_ASSERT_EQUAL_INT((int)sizeof *sent, (int)write(tx_sock[line], sent, sizeof *sent));

	struct can_frame got;
	recv_with_timestamp(rx_sock[line], &got, &stamp);
	TEST_ASSERT_EQUAL_HEX32(sent->can_id, got.can_id);
	TEST_ASSERT_EQUAL_UINT8(sent->len, got.len);
	if (!(sent->can_id & CAN_RTR_FLAG) && sent->len > 0)
		TEST_ASSERT_EQUAL_MEMORY(sent->data, got.data, sent->len);

	TEST_ASSERT_TRUE_MESSAGE(stamp.tv_sec != 0, "no kernel receive timestamp");
	double lag = (double)(stamp.tv_sec - before.tv_sec) +
		     (stamp.tv_nsec - before.tv_nsec) / 1e9;
	TEST_ASSERT_TRUE_MESSAGE(lag > -0.001 && lag < 5.0,
				 "kernel timestamp not near the send time");

	for (int other = 0; other < LINE_COUNT; other++)
		if (other != line)
			TEST_ASSERT_EQUAL_INT_MESSAGE(0, readable_within(rx_sock[other], 50),
						      "frame leaked to another line");
}

static void test_standard_ids_and_every_dlc_on_every_line(void)
{
	for (int line = 0; line < LINE_COUNT; line++) {
		for (uint8_t dlc = 0; dlc <= CAN_MAX_DLEN; dlc++) {
			struct can_frame f = { .can_id = (dlc & 1) ? 0x7FFu : (0x100u + dlc),
					       .len = dlc };
			for (uint8_t b = 0; b < dlc; b++)
				f.data[b] = (uint8_t)(0xA0 + line * 16 + b);
			assert_only_line_receives(line, &f);
		}
	}
}

static void test_extended_29_bit_ids(void)
{
	const canid_t ids[] = { 0, 0x1FFFFFFFu, 0x12345678u & CAN_EFF_MASK, 0x7FFu };
	for (size_t i = 0; i < sizeof ids / sizeof ids[0]; i++) {
		struct can_frame f = { .can_id = ids[i] | CAN_EFF_FLAG,
				       .len = 8,
				       .data = { 1, 2, 3, 4, 5, 6, 7, (uint8_t)i } };
		assert_only_line_receives((int)(i % LINE_COUNT), &f);
	}
}

static void test_remote_frames(void)
{
	struct can_frame std_rtr = { .can_id = 0x701u | CAN_RTR_FLAG, .len = 1 };
	assert_only_line_receives(1, &std_rtr);
	struct can_frame ext_rtr = { .can_id = 0x18FF0001u | CAN_EFF_FLAG | CAN_RTR_FLAG,
				     .len = 0 };
	assert_only_line_receives(2, &ext_rtr);
}

static void test_frames_keep_their_order(void)
{
	for (uint8_t i = 0; i < 50; i++) {
		struct can_frame f = { .can_id = 0x200, .len = 1, .data = { i } };
		TEST_ASSERT_EQUAL_INT((int)sizeof f, (int)write(tx_sock[0], &f, sizeof f));
	}
	for (uint8_t i = 0; i < 50; i++) {
		struct can_frame got;
		struct timespec stamp;
		recv_with_timestamp(rx_sock[0], &got, &stamp);
		TEST_ASSERT_EQUAL_UINT8(i, got.data[0]);
	}
}

static void test_error_frame_reception_can_be_enabled(void)
{
	can_err_mask_t mask = CAN_ERR_MASK, readback = 0;
	socklen_t len = sizeof readback;
	TEST_ASSERT_EQUAL_INT(
		0, setsockopt(rx_sock[0], SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &mask, sizeof mask));
	TEST_ASSERT_EQUAL_INT(
		0, getsockopt(rx_sock[0], SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &readback, &len));
	TEST_ASSERT_EQUAL_HEX32(CAN_ERR_MASK, readback);
	/* Receive-queue overflow counting is what the line driver relies on too. */
	int on = 1;
	TEST_ASSERT_EQUAL_INT(0, setsockopt(rx_sock[0], SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on));
}

static void test_receive_filter_limits_what_arrives(void)
{
	struct can_filter only_0x181 = { .can_id = 0x181,
					 .can_mask = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG };
	TEST_ASSERT_EQUAL_INT(0, setsockopt(rx_sock[2], SOL_CAN_RAW, CAN_RAW_FILTER, &only_0x181,
					    sizeof only_0x181));
	struct can_frame other = { .can_id = 0x182, .len = 2 };
	struct can_frame wanted = { .can_id = 0x181, .len = 2, .data = { 0x55, 0xAA } };
	TEST_ASSERT_EQUAL_INT((int)sizeof other, (int)write(tx_sock[2], &other, sizeof other));
	TEST_ASSERT_EQUAL_INT((int)sizeof wanted, (int)write(tx_sock[2], &wanted, sizeof wanted));
	struct can_frame got;
	struct timespec stamp;
	recv_with_timestamp(rx_sock[2], &got, &stamp);
	TEST_ASSERT_EQUAL_HEX32(0x181, got.can_id);
	TEST_ASSERT_EQUAL_INT(0, readable_within(rx_sock[2], 50));
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_standard_ids_and_every_dlc_on_every_line);
	RUN_TEST(test_extended_29_bit_ids);
	RUN_TEST(test_remote_frames);
	RUN_TEST(test_frames_keep_their_order);
	RUN_TEST(test_error_frame_reception_can_be_enabled);
	RUN_TEST(test_receive_filter_limits_what_arrives);
	return UNITY_END();
}
