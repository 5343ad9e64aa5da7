"""Firmware tapes on which the emulator is known to differ, each with its reason and evidence.

Key: the tape id; value: why the emulator's classic model differs at the tape's first
difference. Each listed tape must still differ (a fix that makes it equal fails the suite until
its entry goes). Never list field-binary texts here (those are ``mirobot_async._tapes.fieldtexts``),
and never loosen a tolerance instead of listing a tape.
"""

from __future__ import annotations

# ruff: noqa: E501 - the keys are the tapes' ids, whole

KNOWN_DIFFERENCES: dict[str, str] = {
    "scenarios-s4/cart_orientation_steps#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "scenarios-s4/cart_relative_stream#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "scenarios-s4/comments_whitespace#0": (
        "'ok' 34-43 ms early: the line waited behind motion whose end the firmware "
        "reached later than the model (end-of-motion timing: GRBL's last step segment, "
        "see the Run-vs-Idle group)"
    ),
    "scenarios-s4/hold_during_dwell#0": (
        "feed hold profile: GRBL starts a hold's deceleration at its next step segment "
        "and plans it from the segment's speed, so the held position (and the resume's "
        "timing) differs from the model's immediate deceleration (e.g. Hold at J1 0.229 "
        "vs 0.159)"
    ),
    "scenarios-s4/hold_resume_twice#0": (
        "feed hold profile: GRBL starts a hold's deceleration at its next step segment "
        "and plans it from the segment's speed, so the held position (and the resume's "
        "timing) differs from the model's immediate deceleration (e.g. Hold at J1 0.229 "
        "vs 0.159)"
    ),
    "scenarios-s4/homing_from_pose#0": (
        "homing from a pose: the firmware's switch search lasts as long as the "
        "simulator's switch model (assumed switch positions, README) needs from that "
        "pose; the model's search has a fixed duration (CLASSIC_HOMING_SECONDS from the "
        "zero pose), so the reply differs by the extra travel (0.7-1.5 s)"
    ),
    "scenarios-s4/homing_recovers_alarm#0": (
        "float32 FK last digit: the Alarm status's Cartesian Y prints 53.843 on the "
        "firmware, 53.844 here, with equal angles (float32.py: about one pose in "
        "thirteen)"
    ),
    "scenarios-s4/homing_seq_from_pose#0": (
        "homing from a pose: the firmware's switch search lasts as long as the "
        "simulator's switch model (assumed switch positions, README) needs from that "
        "pose; the model's search has a fixed duration (CLASSIC_HOMING_SECONDS from the "
        "zero pose), so the reply differs by the extra travel (0.7-1.5 s)"
    ),
    "scenarios-s4/long_cart_program#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "scenarios-s4/long_joint_program#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "scenarios-s4/mode_switch_relative#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "scenarios-s4/reset_midstream_recovery#0": (
        "position frozen by an abort: after '%' during motion the Alarm status shows "
        "where the stepper stopped, a motion sample: the firmware's is 1 step (or, at a "
        "move's first ms, 9 steps) away from the model's continuous profile (acceleration "
        "ramps run ~10 ms behind the ideal trapezoid, motion/__init__ 'Not modelled'); at "
        "rest the replay compares it exactly"
    ),
    "scenarios-s4/rx_buffer_boundary#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "scenarios-s4/status_during_parse#0": (
        "report before the reply of a motion line: GRBL's mc_line calls "
        "protocol_execute_realtime before it plans the block, so a '?' that arrives "
        "during the line's parse before that point is answered (Idle, block not yet "
        "queued) before the 'ok'; the model answers a '?' during a parse only after the "
        "reply (or at a wait)"
    ),
    "scenarios-s4/status_poll_motion#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
    "tests/integration/test_alarm_cleared_by_every_path.py::test_an_undocumented_homing_variant_that_homes_clears_the_alarm[classic]#0": (
        "position frozen by an abort: after '%' during motion the Alarm status shows "
        "where the stepper stopped, a motion sample: the firmware's is 1 step (or, at a "
        "move's first ms, 9 steps) away from the model's continuous profile (acceleration "
        "ramps run ~10 ms behind the ideal trapezoid, motion/__init__ 'Not modelled'); at "
        "rest the replay compares it exactly"
    ),
    "tests/integration/test_cli.py::test_run_on_a_classic_port#0": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_client.py::test_hold_on_exit_holds_the_arm_when_the_block_fails[classic]#0": (
        "feed hold profile: GRBL starts a hold's deceleration at its next step segment "
        "and plans it from the segment's speed, so the held position (and the resume's "
        "timing) differs from the model's immediate deceleration (e.g. Hold at J1 0.229 "
        "vs 0.159)"
    ),
    "tests/integration/test_client.py::test_home_then_moves[classic]#0": (
        "homing from a pose: the firmware's switch search lasts as long as the "
        "simulator's switch model (assumed switch positions, README) needs from that "
        "pose; the model's search has a fixed duration (CLASSIC_HOMING_SECONDS from the "
        "zero pose), so the reply differs by the extra travel (0.7-1.5 s) (its second "
        "homing, $HH, starts from a pose)"
    ),
    "tests/integration/test_client.py::test_readme_example_runs_as_written[classic]#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
    "tests/integration/test_client.py::test_reset_during_motion_leaves_an_alarm[classic]#0": (
        "position frozen by an abort: after '%' during motion the Alarm status shows "
        "where the stepper stopped, a motion sample: the firmware's is 1 step (or, at a "
        "move's first ms, 9 steps) away from the model's continuous profile (acceleration "
        "ramps run ~10 ms behind the ideal trapezoid, motion/__init__ 'Not modelled'); at "
        "rest the replay compares it exactly"
    ),
    "tests/integration/test_client.py::test_wait_true_detects_completion_promptly[classic]#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
    "tests/integration/test_client_envelope.py::test_a_stream_stops_before_the_line_that_leaves_the_envelope[classic-False]#0": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_client_envelope.py::test_after_homing_the_position_is_read_before_the_next_move[classic]#0": (
        "homing from a pose: the firmware's switch search lasts as long as the "
        "simulator's switch model (assumed switch positions, README) needs from that "
        "pose; the model's search has a fixed duration (CLASSIC_HOMING_SECONDS from the "
        "zero pose), so the reply differs by the extra travel (0.7-1.5 s)"
    ),
    "tests/integration/test_client_envelope.py::test_concurrent_moves_are_checked_in_the_order_they_are_written[classic]#0": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_client_envelope.py::test_moves_inside_the_envelope_arrive_byte_for_byte[classic]#0": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_client_envelope.py::test_opting_out_is_loud_and_sends[classic]#0": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_client_envelope.py::test_the_position_is_read_again_after_an_unchecked_move[classic]#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
    "tests/integration/test_client_paths.py::test_move_path_streams_bare_lines_and_ends_idle_at_the_last_point[classic]#0": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_client_paths.py::test_the_envelope_checks_the_whole_path_first[classic]#0": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_client_streaming.py::test_stream_with_status_polling_alongside[classic]#0": (
        "report before the reply of an M3 line: GRBL 0.9j's spindle_run synchronises with "
        "the planner (protocol_buffer_synchronize -> protocol_execute_realtime) even with "
        "nothing queued, so a '?' that arrives during an 'M3 S..' line is answered before "
        "its 'ok'; the model's wait point exists only for a line that waits for queued "
        "motion"
    ),
    "tests/integration/test_completion_polling.py::test_a_motion_wait_pipelines_status_requests_without_merged_ones[classic]#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
    "tests/integration/test_envelope_default_deny.py::test_homing_variants_forget_the_position[classic]#0": (
        "homing from a pose: the firmware's switch search lasts as long as the "
        "simulator's switch model (assumed switch positions, README) needs from that "
        "pose; the model's search has a fixed duration (CLASSIC_HOMING_SECONDS from the "
        "zero pose), so the reply differs by the extra travel (0.7-1.5 s)"
    ),
    "tests/integration/test_envelope_default_deny.py::test_units_unknown_at_connect_must_be_stated[classic]#0": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_random_faults.py::test_random_faults_never_mix_up_calls[classic-pipelined]#0": (
        "report before the reply of an M3 line: GRBL 0.9j's spindle_run synchronises with "
        "the planner (protocol_buffer_synchronize -> protocol_execute_realtime) even with "
        "nothing queued, so a '?' that arrives during an 'M3 S..' line is answered before "
        "its 'ok'; the model's wait point exists only for a line that waits for queued "
        "motion"
    ),
    "tests/integration/test_resets.py::test_reset_during_a_waited_move_raises_reset_error[classic]#0": (
        "the firmware's status was cut by the reset (its last bytes 'ALARu': '%' arrived "
        "while it was being sent), and its position shows the move 1 step in; the model's "
        "report is whole and its move not yet started (start latency)"
    ),
    "tests/integration/test_resets.py::test_reset_mid_stream[classic-reset()]#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision); after the reset the replies "
        "shift accordingly"
    ),
    "tests/integration/test_resets.py::test_reset_mid_stream[classic-spontaneous]#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision); after the reset the replies "
        "shift accordingly"
    ),
    "tests/integration/test_stream_meaning.py::test_streamed_programs_end_where_stepped_ones_do[classic]#21": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_stream_meaning.py::test_streamed_programs_end_where_stepped_ones_do[classic]#22": (
        "reply before report: the firmware's 'ok' of a line queued behind motion came "
        "before the '?' was answered because its motion (and so the wait) ended earlier "
        "than the model's: end-of-motion timing of GRBL's last step segment"
    ),
    "tests/integration/test_stream_meaning.py::test_streamed_programs_end_where_stepped_ones_do[classic]#23": (
        "float32 FK last digit or one motor step in a chained end position: status "
        "position at the end of a streamed chain: the firmware's Idle status shows the "
        "last joints a motor step off the model's (GRBL's per-block step rounding of the "
        "chained blocks, which the model computes from the continuous targets); at rest "
        "so compared exactly"
    ),
    "tests/integration/test_stream_meaning.py::test_streamed_programs_end_where_stepped_ones_do[classic]#27": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_stream_meaning.py::test_streamed_programs_end_where_stepped_ones_do[classic]#33": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_stream_meaning.py::test_streamed_programs_end_where_stepped_ones_do[classic]#35": (
        "float32 FK last digit or one motor step in a chained end position: status "
        "position at the end of a streamed chain: the firmware's Idle status shows the "
        "last joints a motor step off the model's (GRBL's per-block step rounding of the "
        "chained blocks, which the model computes from the continuous targets); at rest "
        "so compared exactly"
    ),
    "tests/integration/test_stream_meaning.py::test_streamed_programs_end_where_stepped_ones_do[classic]#37": (
        "float32 FK last digit or one motor step in a chained end position: status "
        "position at the end of a streamed chain: the firmware's Idle status shows the "
        "last joints a motor step off the model's (GRBL's per-block step rounding of the "
        "chained blocks, which the model computes from the continuous targets); at rest "
        "so compared exactly"
    ),
    "tests/integration/test_stream_meaning.py::test_streamed_programs_end_where_stepped_ones_do[classic]#45": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_stream_meaning.py::test_streamed_programs_end_where_stepped_ones_do[classic]#53": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_stream_meaning.py::test_the_clients_own_moves_chain_without_waiting[classic]#11": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_stream_meaning.py::test_the_clients_own_moves_chain_without_waiting[classic]#12": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_stream_meaning.py::test_the_clients_own_moves_chain_without_waiting[classic]#13": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_stream_meaning.py::test_the_clients_own_moves_chain_without_waiting[classic]#16": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_stream_meaning.py::test_the_clients_own_moves_chain_without_waiting[classic]#23": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/integration/test_stream_meaning.py::test_the_clients_own_moves_chain_without_waiting[classic]#28": (
        "status state word at the end of motion: the firmware still reports Run at (or a "
        "step from) the final position for a few ms after the model's continuous "
        "trapezoid has ended and reports Idle (GRBL ends a move when its stepper has run "
        "out the last 10 ms step segment of the deceleration; the model does not run "
        "GRBL's segment generator). First difference: firmware <Run,...> vs emulator "
        "<Idle,...> with equal angles"
    ),
    "tests/oracle/test_diff_chaining.py::test_streamed_programs_end_where_stepped_ones_do#0": (
        "reply before report: the firmware's 'ok' of a line queued behind motion came "
        "before the '?' was answered because its motion (and so the wait) ended earlier "
        "than the model's: end-of-motion timing of GRBL's last step segment"
    ),
    "tests/oracle/test_diff_chaining.py::test_the_clients_own_moves_chain_without_waiting#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
    "tests/oracle/test_diff_fuzz.py::test_random_lines#5": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_motion.py::test_burst[m21-resync-25-two-axes]#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "tests/oracle/test_diff_motion.py::test_burst[m21-resync-30-slow]#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "tests/oracle/test_diff_motion.py::test_move[cart-g1-fk-digit]#0": (
        "float32 FK last digit: the Idle status's Cartesian numbers differ in their last "
        "digit with equal angles (float32.py: the firmware's order of FK operations is "
        "not known)"
    ),
    "tests/oracle/test_diff_motion.py::test_move[cart-orientation]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_motion.py::test_overflowing_burst[m20-rel-g1-20]#0": (
        "reply before report: the firmware's 'ok' of a line queued behind motion came "
        "before the '?' was answered because its motion (and so the wait) ended earlier "
        "than the model's: wrist-heavy move timing"
    ),
    "tests/oracle/test_diff_motion.py::test_unreachable[cart-wrist-out-soft-off]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_outputs.py::test_answered_at_once[$#]#0": (
        "'ok' 34-43 ms early: the line waited behind motion whose end the firmware "
        "reached later than the model (end-of-motion timing: GRBL's last step segment, "
        "see the Run-vs-Idle group)"
    ),
    "tests/oracle/test_diff_stream.py::test_burst_fills_planner#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "tests/oracle/test_diff_stream.py::test_feed_hold_and_resume#0": (
        "feed hold profile: GRBL starts a hold's deceleration at its next step segment "
        "and plans it from the segment's speed, so the held position (and the resume's "
        "timing) differs from the model's immediate deceleration (e.g. Hold at J1 0.229 "
        "vs 0.159)"
    ),
    "tests/oracle/test_diff_stream.py::test_reset_during_motion#0": (
        "position frozen by an abort: after '%' during motion the Alarm status shows "
        "where the stepper stopped, a motion sample: the firmware's is 1 step (or, at a "
        "move's first ms, 9 steps) away from the model's continuous profile (acceleration "
        "ramps run ~10 ms behind the ideal trapezoid, motion/__init__ 'Not modelled'); at "
        "rest the replay compares it exactly"
    ),
    "tests/oracle/test_diff_stream.py::test_reset_keeps_the_alarm#0": (
        "the README's failed oracle test: '%' came 11 ms after the move's ok and the "
        "firmware had not started that move (no abort alarm); the model's motion starts "
        "1.75 ms after a cycle start (CYCLE_START_LATENCY), so it prints ALARM: Abort "
        "during cycle"
    ),
    "tests/oracle/test_diff_stream.py::test_stream_fills_planner#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "tests/oracle/test_diff_timing.py::test_program_time[cart-g1-200-segments]#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "tests/oracle/test_diff_timing.py::test_program_time[joint-short-segments]#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-off M20 G90 X200 Y0 Z170 A0 B0 C180-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-off M20 G90 X200 Y0 Z170 A0 B0 C180-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-off M20 G90 X200 Y0 Z170 A0 B90 C0-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-off M20 G90 X200 Y0 Z170 A90 B0 C0-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-off M20 G90 X200 Y0 Z170 A90 B0 C0-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-off M20 G91 A90-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-off M20 G91 A90-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-off M20 G91 B60-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-off M20 G91 B60-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-off M20 G91 C-200-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-off M20 G91 C-200-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G90 X200 Y0 Z170 A0 B-90 C0-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G90 X200 Y0 Z170 A0 B-90 C0-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G90 X200 Y0 Z170 A0 B0 C180-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G90 X200 Y0 Z170 A0 B0 C180-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G90 X200 Y0 Z170 A180 B0 C0-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G90 X200 Y0 Z170 A180 B0 C0-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G90 X200 Y0 Z170 A90 B0 C0-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G90 X200 Y0 Z170 A90 B0 C0-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G91 A90-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G91 A90-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G91 B-60-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G91 C-200-G0]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_diff_workspace.py::test_target[soft-on M20 G91 C-200-G1 F2000]#0": (
        "wrist-heavy moves end early on the firmware: moves dominated by J4..J6 (16, "
        "22.22, 11.11 steps/deg) finish 20-50 ms before the model's ideal trapezoid "
        "($12x=50 deg/s^2), so the G4 P0 'ok' comes before the model's and a '?' after it "
        "finds the model still Run (e.g. test_random_lines#5: 'G1 C9' at F200 takes 2.727 "
        "s on the firmware, 2.767 s as a trapezoid); GRBL's step-segment execution at low "
        "step rates is not modelled"
    ),
    "tests/oracle/test_replay_motion.py::test_replay[cart-g0]#0": (
        "report before the reply: a '?' that arrives while the firmware prepares the "
        "first step segments of a move it has just started (the line after the one that "
        "starts a move takes up to 2.7 ms more, linecost 'Not modelled') is answered "
        "before that line's 'ok'; the model answers after the reply"
    ),
    "tests/oracle/test_replay_motion.py::test_replay[cart-g1]#0": (
        "report before the reply: a '?' that arrives while the firmware prepares the "
        "first step segments of a move it has just started (the line after the one that "
        "starts a move takes up to 2.7 ms more, linecost 'Not modelled') is answered "
        "before that line's 'ok'; the model answers after the reply"
    ),
    "tests/oracle/test_replay_motion.py::test_replay[hold-resume]#0": (
        "report before the reply: a '?' that arrives while the firmware prepares the "
        "first step segments of a move it has just started (the line after the one that "
        "starts a move takes up to 2.7 ms more, linecost 'Not modelled') is answered "
        "before that line's 'ok'; the model answers after the reply"
    ),
    "tests/oracle/test_replay_motion.py::test_replay[joint]#0": (
        "report before the reply: a '?' that arrives while the firmware prepares the "
        "first step segments of a move it has just started (the line after the one that "
        "starts a move takes up to 2.7 ms more, linecost 'Not modelled') is answered "
        "before that line's 'ok'; the model answers after the reply"
    ),
    "tests/oracle/test_replay_motion.py::test_replay[stream]#0": (
        "'ok' instants of lines waiting for a planner slot in streams: the firmware frees "
        "a slot when its stepper discards a block at the end of its last step segment, "
        "and replans the queue in float32 with GRBL's junction rules; the model's block "
        "ends and junction speeds differ by 30-90 ms over a stream of short blocks "
        "(planner timing not modelled to that precision)"
    ),
    "tests/realtime/test_oracle_client.py::test_dwell_behind_a_move_runs_in_idle_and_is_not_given_up#0": (
        "float32 FK last digit or one motor step in a chained end position: status "
        "position at the end of a streamed chain: the firmware's Idle status shows the "
        "last joints a motor step off the model's (GRBL's per-block step rounding of the "
        "chained blocks, which the model computes from the continuous targets); at rest "
        "so compared exactly"
    ),
    "tests/realtime/test_oracle_client.py::test_home_on_the_real_firmware#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
    "tests/realtime/test_oracle_client.py::test_sequential_home_on_the_real_firmware#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
    "tests/realtime/test_user_flows_cli.py::test_ctrl_c_while_a_program_runs[oracle]#0": (
        "report before the reply: a '?' that arrives while the firmware prepares the "
        "first step segments of a move it has just started (the line after the one that "
        "starts a move takes up to 2.7 ms more, linecost 'Not modelled') is answered "
        "before that line's 'ok'; the model answers after the reply"
    ),
    "tests/realtime/test_user_flows_cli.py::test_every_moving_command_on_a_port[oracle]#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
    "tests/realtime/test_user_flows_cli.py::test_pick_and_place_as_its_comment_says[oracle]#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
    "tests/realtime/test_user_flows_library.py::test_a_move_of_twenty_seconds[oracle]#0": (
        "report before the reply of a motion line: GRBL's mc_line calls "
        "protocol_execute_realtime before it plans the block, so a '?' that arrives "
        "during the line's parse before that point is answered (Idle, block not yet "
        "queued) before the 'ok'; the model answers a '?' during a parse only after the "
        "reply (or at a wait)"
    ),
    "tests/realtime/test_user_flows_library.py::test_homing_with_a_monitor_thread_running[oracle]#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
    "tests/realtime/test_user_flows_library.py::test_readme_script_example_on_a_port[oracle]#0": (
        "status compute time during motion: while the stepper interrupt runs the firmware "
        "takes 2-12 ms (growing with the step rate) to produce a report, so a '?' about "
        "15-20 ms after the previous one is merged (no reply) or answered later; the "
        "model uses the at-rest compute time (uart.py: 'ASSUMED ... the model does not "
        "know that load'). First difference: a status instant or a merged '?' about "
        "-20..-38 ms"
    ),
}
