from datetime import UTC, datetime
from io import BytesIO
from pathlib import Path

import can
import cantools
import pytest

import firmware_bridge
from firmware_bridge.can_export import export_can_log, record_to_message
from firmware_bridge.can_link import CanLink
from firmware_bridge.errors import BridgeOperationError, BridgeSetupError, FrameError
from hil.vesc_sim import SimVescBank
from logs.clock import SimClock
from logs.errors import NotARecording
from logs.read_stop import CUT, DAMAGED
from logs.reader import read_messages
from logs.recorder import McapRecorder
from logs.topics import CAN_FRAMES, stamp
from logs.wall_clock import WALL_CLOCK_METADATA, WallClockAnchor
from rover_cli.main import main
from tests.firmware_bridge.virtual_can import make_codec, virtual_bus_pair
from tests.logs.damaged_recording import damage_a_middle_chunk

SHIPPED_DBC = Path(firmware_bridge.__file__).parent / "vesc_6wheel.dbc"
TICK_NS = 10_000_000


def record_a_run(label: str, ticks: int = 30) -> bytes:
    """A short lockstep run of CanLink against the simulated controllers, recorded to MCAP in memory."""
    stream = BytesIO()
    clock = SimClock(1_000_000_000)
    with (
        virtual_bus_pair(label) as (ours, theirs),
        McapRecorder(stream, chunk_duration_ns=5 * TICK_NS) as recorder,
    ):
        link = CanLink(ours, make_codec(), clock, recorder)
        bank = SimVescBank(theirs, make_codec(), clock)
        for tick in range(ticks):
            if tick % 2 == 0:
                link.send_wheel_speeds([0.4, 0.4, 0.4, -0.2, -0.2, -0.2])
            bank.poll()
            bank.step(TICK_NS / 1e9)
            link.poll()
            clock.advance(TICK_NS)
    return stream.getvalue()


def test_export_reads_back_identical_and_decodes_with_the_shipped_dbc(request, tmp_path):
    recording = record_a_run(request.node.name)
    recorded = list(read_messages(BytesIO(recording), topics=[CAN_FRAMES]))
    out = tmp_path / "run.log"
    stats = export_can_log(BytesIO(recording), out, channel="vcan0")
    assert stats.frames == len(recorded) > 100
    assert stats.tx == sum(r.message["direction"] == "tx" for r in recorded) > 0
    assert stats.rx == stats.frames - stats.tx > 0
    assert stats.rejected == 0 and not stats.truncated
    assert (stats.first_ns, stats.last_ns) == (recorded[0].log_time_ns, recorded[-1].log_time_ns)

    read_back = list(can.CanutilsLogReader(out))
    assert len(read_back) == len(recorded)
    for msg, rec in zip(read_back, recorded, strict=True):
        frame = rec.message
        assert msg.arbitration_id == frame["id"]
        assert msg.is_extended_id == frame["extended"]
        assert msg.dlc == frame["dlc"]
        assert bytes(msg.data).hex() == frame["data"]
        assert msg.is_rx == (frame["direction"] == "rx")
        assert msg.channel == "vcan0"
        assert round(msg.timestamp * 1e9) == rec.log_time_ns  # lockstep times are whole microseconds

    database = cantools.database.load_file(str(SHIPPED_DBC), database_format="dbc", strict=True)
    profile = make_codec().profile
    commanded = {round(profile.erpm_from_speed(0.4)), round(profile.erpm_from_speed(-0.2))}
    names = set()
    for msg in read_back:
        message = database.get_message_by_frame_id(msg.arbitration_id, force_extended_id=msg.is_extended_id)
        decoded = message.decode(bytes(msg.data))  # strict decoding: raises on a malformed frame
        names.add(message.name)
        if message.name.startswith("VESC_SET_RPM_C"):
            assert not msg.is_rx and decoded["erpm"] in commanded
    assert {"VESC_SET_RPM_C1", "VESC_STATUS_C6", "VESC_STATUS_4_C3", "VESC_STATUS_5_C2"} <= names


def test_bad_records_are_counted_and_skipped_not_fatal(tmp_path):
    stream = BytesIO()
    good = {
        "timestamp": stamp(1_000),
        "direction": "rx",
        "id": 0x901,
        "extended": True,
        "dlc": 2,
        "data": "0102",
    }
    with McapRecorder(stream) as recorder:
        recorder.publish(CAN_FRAMES, 1_000, good)
        recorder.publish(CAN_FRAMES, 2_000, {**good, "data": "zz"})
        recorder.publish(CAN_FRAMES, 3_000, {**good, "dlc": 3})
        recorder.publish(CAN_FRAMES, 4_000, {**good, "id": 0x901, "extended": False})
        recorder.publish(CAN_FRAMES, 5_000, {**good, "direction": "sideways"})
        recorder.publish(CAN_FRAMES, 6_000, {**good, "direction": "tx", "id": 0x123, "extended": False})
    out = tmp_path / "bad.log"
    stats = export_can_log(BytesIO(stream.getvalue()), out)
    assert (stats.frames, stats.rejected) == (2, 4)
    lines = out.read_text().splitlines()
    assert lines == ["(0.000001) can0 00000901#0102 R", "(0.000006) can0 123#0102 T"]


def test_an_error_frame_record_exports_as_an_error_frame(tmp_path):
    """A record marked "error" (the controller's bus-off report) is exported as python-can writes an error
    frame (candump: its CAN_ERR_FLAG line) and counted as received; an unmarked one stays a data frame."""
    stream = BytesIO()
    busoff = {"direction": "rx", "id": 0x40, "extended": False, "dlc": 8, "data": "00" * 8, "error": True}
    with McapRecorder(stream) as recorder:
        recorder.publish(CAN_FRAMES, 1_000, {"timestamp": stamp(1_000), **busoff})
        recorder.publish(CAN_FRAMES, 2_000, {"timestamp": stamp(2_000), **busoff, "error": False})
    out = tmp_path / "errors.log"
    stats = export_can_log(BytesIO(stream.getvalue()), out)
    assert (stats.frames, stats.rx, stats.error_frames, stats.rejected) == (2, 2, 1, 0)
    error, data = can.CanutilsLogReader(out)
    assert error.is_error_frame and not data.is_error_frame and data.arbitration_id == 0x40


@pytest.mark.parametrize(
    ("suffix", "error_back"),
    [
        (".log", (True, 0)),
        (".asc", (True, 0)),
        (".blf", (True, 0x40)),
        (".csv", (True, 0x40)),
        (".trc", None),
    ],
)
def test_every_format_reads_back_what_the_export_counts(tmp_path, suffix, error_back):
    """Each format's reader gets back the frames the export says it wrote; an error frame as far as the
    format keeps it (candump and .asc lose its class, .trc has no line for it: left out and counted)."""
    stream = BytesIO()
    data = {"direction": "rx", "id": 0x901, "extended": True, "dlc": 2, "data": "0102"}
    busoff = {"direction": "rx", "id": 0x40, "extended": False, "dlc": 8, "data": "00" * 8, "error": True}
    with McapRecorder(stream) as recorder:
        recorder.publish(CAN_FRAMES, 1_000, {"timestamp": stamp(1_000), **data})
        recorder.publish(CAN_FRAMES, 2_000, {"timestamp": stamp(2_000), **busoff})
    out = tmp_path / f"run{suffix}"
    stats = export_can_log(BytesIO(stream.getvalue()), out)
    back = list(can.LogReader(out))
    assert len(back) == stats.frames
    assert [(m.arbitration_id, m.is_error_frame) for m in back][:1] == [(0x901, False)]
    if error_back is None:
        assert (stats.frames, stats.error_frames, stats.error_frames_dropped) == (1, 0, 1)
    else:
        assert (stats.frames, stats.error_frames, stats.error_frames_dropped) == (2, 1, 0)
        assert (back[1].is_error_frame, back[1].arbitration_id) == error_back


def test_a_recording_of_error_frames_alone_exports_to_trc_empty_and_says_so(tmp_path, capsys):
    """A run bus-off throughout: its can/frames holds error records only, which .trc cannot hold. The
    export writes the empty log, counts them, and exits 1 (not everything exported), not 2 (no frames)."""
    busoff = {"direction": "rx", "id": 0x40, "extended": False, "dlc": 8, "data": "00" * 8, "error": True}
    recording = tmp_path / "bus_off.mcap"
    with recording.open("wb") as stream, McapRecorder(stream) as recorder:
        recorder.publish(CAN_FRAMES, 1_000, {"timestamp": stamp(1_000), **busoff})
    out = tmp_path / "bus_off.trc"
    stats = export_can_log(recording, out)
    assert (stats.frames, stats.error_frames_dropped) == (0, 1) and out.exists()
    assert main(["can", "export", str(recording), str(tmp_path / "again.trc")]) == 1
    assert "1 error frames left out" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("record", "text"),
    [
        ({"direction": "rx", "id": 1, "extended": True, "dlc": 1}, "malformed"),
        ({"direction": "rx", "id": -1, "extended": True, "dlc": 0, "data": ""}, "out of range"),
        ({"direction": "rx", "id": 1, "extended": True, "dlc": 9, "data": "00" * 9}, "dlc 9"),
        ({"direction": "rx", "id": 0x40, "extended": False, "dlc": 0, "data": "", "error": 1}, "error=1"),
        (
            {"direction": "rx", "id": 1 << 29, "extended": False, "dlc": 0, "data": "", "error": True},
            "out of range",
        ),
    ],
)
def test_record_to_message_names_what_is_wrong(record, text):
    with pytest.raises(FrameError, match=text) as caught:
        record_to_message(record, 0, "can0")
    assert caught.value.reason == "record"


def test_an_error_frames_class_may_use_all_29_bits_whatever_its_format():
    # python-can's socketcan gives an error frame a standard-format id holding the class, of Linux's 29-bit
    # CAN_ERR_MASK (the classes it defines end at 0x200; a driver may set more).
    record = {"direction": "rx", "id": 0x1000, "extended": False, "dlc": 0, "data": "", "error": True}
    msg = record_to_message(record, 5, "can0")
    assert msg.is_error_frame and msg.arbitration_id == 0x1000 and not msg.is_extended_id
    with pytest.raises(FrameError, match="out of range"):
        record_to_message({**record, "error": False}, 5, "can0")  # past a standard data frame's 0x7ff


def test_other_formats_by_suffix_and_refusals(request, tmp_path):
    recording = record_a_run(request.node.name, ticks=4)
    stats = export_can_log(BytesIO(recording), tmp_path / "run.asc")
    assert len(list(can.ASCReader(tmp_path / "run.asc"))) == stats.frames > 0
    with pytest.raises(BridgeSetupError, match="unknown CAN log suffix"):
        export_can_log(BytesIO(recording), tmp_path / "run.txt")
    with pytest.raises(BridgeSetupError, match="without spaces"):
        export_can_log(BytesIO(recording), tmp_path / "run.log", channel="can 0")
    with pytest.raises(BridgeOperationError, match="cannot export"):
        export_can_log(BytesIO(b"not an mcap file at all"), tmp_path / "x.log")
    # An output folder, as other commands take (--out DIR): named as one, not as a log with suffix ''.
    with pytest.raises(BridgeSetupError) as caught:
        export_can_log(BytesIO(recording), tmp_path)
    example = tmp_path / "can.log"
    assert str(caught.value) == f"{tmp_path} is a folder: name the log file in it, e.g. {example}"


def frame_fields(msg: can.Message) -> tuple[int, bool, int, bytes]:
    return msg.arbitration_id, msg.is_extended_id, msg.dlc, bytes(msg.data)


@pytest.mark.parametrize("suffix", [".log", ".asc", ".blf", ".trc", ".csv"])
def test_python_can_reads_every_export_format_back_with_the_same_frames(request, tmp_path, suffix):
    recording = record_a_run(request.node.name, ticks=6)
    recorded = [m.message for m in read_messages(BytesIO(recording), topics=[CAN_FRAMES])]
    out = tmp_path / f"run{suffix}"
    stats = export_can_log(BytesIO(recording), out)
    read_back = list(can.LogReader(out))
    assert len(read_back) == stats.frames == len(recorded) > 0
    expected = [(r["id"], r["extended"], r["dlc"], bytes.fromhex(r["data"])) for r in recorded]
    assert [frame_fields(m) for m in read_back] == expected
    if suffix != ".csv":  # python-can's CSV has no direction column (next test)
        assert [m.is_rx for m in read_back] == [r["direction"] == "rx" for r in recorded]


def test_a_csv_export_warns_that_sent_frames_read_back_as_received(request, tmp_path, caplog):
    recording = record_a_run(request.node.name, ticks=4)
    with caplog.at_level("WARNING", logger="firmware_bridge.can_export"):
        stats = export_can_log(BytesIO(recording), tmp_path / "run.csv")
    assert stats.tx > 0
    assert (
        f"no direction column: the {stats.tx} frames the companion sent read back as received" in caplog.text
    )
    caplog.clear()
    with caplog.at_level("WARNING", logger="firmware_bridge.can_export"):
        export_can_log(BytesIO(recording), tmp_path / "run.log")
    assert "direction" not in caplog.text


def test_a_recording_cut_short_exports_up_to_the_cut(request, tmp_path):
    recording = record_a_run(request.node.name)
    whole = export_can_log(BytesIO(recording), tmp_path / "whole.log")
    cut = export_can_log(BytesIO(recording[: len(recording) // 2]), tmp_path / "cut.log")
    assert cut.truncated
    assert cut.frames < whole.frames
    assert len((tmp_path / "cut.log").read_text().splitlines()) == cut.frames


EXPORTED_AT = datetime(2026, 3, 4, 5, 6, 7, tzinfo=UTC)  # the "now" handed to an export


def exported_at() -> int:
    return round(EXPORTED_AT.timestamp() * 1e9)


def asc_dates(path: Path) -> list[str]:
    """The header's two dates: the ``date`` line and ``Begin Triggerblock``."""
    lines = path.read_text().splitlines()
    return [line.split(" ", 1)[1] for line in lines if line.startswith("date ")] + [
        line.split(" ", 2)[2] for line in lines if line.startswith("Begin Triggerblock ")
    ]


def local_asc_date(moment: datetime) -> str:
    local = moment.astimezone()  # ASC dates are local time, milliseconds as python-can writes them
    return local.strftime(can.ASCWriter.FORMAT_DATE.format(local.microsecond // 1000))


def test_a_recording_without_a_wall_clock_is_dated_at_export_and_says_so(request, tmp_path):
    recording = record_a_run(request.node.name, ticks=6)  # lockstep: simulated time, no wall_clock record
    first_ns = next(iter(read_messages(BytesIO(recording), topics=[CAN_FRAMES]))).log_time_ns
    for suffix in (".asc", ".trc"):
        stats = export_can_log(BytesIO(recording), tmp_path / f"run{suffix}", wall_ns=exported_at)
        assert stats.wall_clock_start is None
        text = (tmp_path / f"run{suffix}").read_text()
        assert "1970" not in text
        assert "no wall-clock start" in text and "dated at export, 2026-03-04T05:06:07.000+00:00" in text
    assert asc_dates(tmp_path / "run.asc") == [local_asc_date(EXPORTED_AT)] * 2
    with can.TRCReader(tmp_path / "run.trc") as reader:
        frames = list(reader)  # the header is read with the first frame
        assert reader.start_time == EXPORTED_AT  # frames keep their spacing from the first
    with can.ASCReader(tmp_path / "run.asc", relative_timestamp=False) as asc:
        asc_frames = list(asc)
    recorded = list(read_messages(BytesIO(recording), topics=[CAN_FRAMES]))
    for rec, trc, asc_frame in zip(recorded, frames, asc_frames, strict=True):
        expected = EXPORTED_AT.timestamp() + (rec.log_time_ns - first_ns) / 1e9
        assert trc.timestamp == pytest.approx(expected, abs=1e-3)  # TRC keeps milliseconds
        assert asc_frame.timestamp == pytest.approx(expected, abs=2e-3)  # ASC: ms header, us frames
    # candump keeps the recording's own clock: it has no header to date.
    export_can_log(BytesIO(recording), tmp_path / "run.log", wall_ns=exported_at)
    read_back = list(can.CanutilsLogReader(tmp_path / "run.log"))
    assert [round(m.timestamp * 1e9) for m in read_back] == [r.log_time_ns for r in recorded]


def test_a_recording_with_a_wall_clock_is_dated_by_it(request, tmp_path):
    started = datetime(2025, 7, 8, 9, 10, 11, 250_000, tzinfo=UTC)
    anchor = WallClockAnchor(unix_ns=round(started.timestamp() * 1e9), clock_ns=1_000_000_000)
    source = BytesIO(record_a_run(request.node.name, ticks=6))
    recording = BytesIO()
    with McapRecorder(recording) as recorder:  # the run again, with rover run's wall_clock record first
        recorder.add_metadata(WALL_CLOCK_METADATA, anchor.as_metadata())
        for rec in read_messages(source, topics=[CAN_FRAMES]):
            recorder.publish(CAN_FRAMES, rec.log_time_ns, rec.message)
    recorded = list(read_messages(BytesIO(recording.getvalue()), topics=[CAN_FRAMES]))
    first = datetime.fromtimestamp(anchor.unix_ns_at(recorded[0].log_time_ns) / 1e9, UTC)
    for suffix in (".asc", ".trc", ".log"):
        stats = export_can_log(BytesIO(recording.getvalue()), tmp_path / f"run{suffix}", wall_ns=exported_at)
        assert stats.wall_clock_start == first.isoformat(timespec="microseconds")
        assert "2026" not in (tmp_path / f"run{suffix}").read_text()  # the export time is not used
    assert asc_dates(tmp_path / "run.asc") == [local_asc_date(first)] * 2
    assert "the recording's wall-clock start" in (tmp_path / "run.asc").read_text()
    with can.TRCReader(tmp_path / "run.trc") as reader:
        assert len(list(reader)) == len(recorded)
        assert reader.start_time == first
    read_back = list(can.CanutilsLogReader(tmp_path / "run.log"))  # candump: Unix times, as candump -l
    for msg, rec in zip(read_back, recorded, strict=True):
        assert msg.timestamp == pytest.approx(anchor.unix_ns_at(rec.log_time_ns) / 1e9, abs=1e-6)


def test_a_recording_damaged_partway_exports_up_to_the_damage_and_says_where(request, tmp_path):
    recording, damaged_at = damage_a_middle_chunk(record_a_run(request.node.name))
    before = list(read_messages(BytesIO(recording[:damaged_at]), topics=[CAN_FRAMES]))
    stats = export_can_log(BytesIO(recording), tmp_path / "damaged.log")
    assert stats.stop is not None and (stats.stop.kind, stats.stop.offset) == (DAMAGED, damaged_at)
    assert not stats.truncated  # damaged, not cut: the bytes go on after it
    assert stats.frames == len(before) > 0
    lines = (tmp_path / "damaged.log").read_text().splitlines()
    assert [int(line.split()[2].split("#")[0], 16) for line in lines] == [r.message["id"] for r in before]


def test_a_cut_recording_says_where_it_was_cut(request, tmp_path):
    recording = record_a_run(request.node.name)
    stats = export_can_log(BytesIO(recording[: len(recording) // 2]), tmp_path / "cut.log")
    assert stats.stop is not None and stats.stop.kind == CUT and 0 < stats.stop.offset < len(recording) // 2


@pytest.mark.parametrize(
    "content", [b"", b"\x89MCAP", b"PK\x03\x04 a zip file"], ids=["empty", "5-bytes", "zip"]
)
def test_a_file_with_no_recording_in_it_is_an_error_and_writes_nothing(content, tmp_path):
    out = tmp_path / "run.log"
    with pytest.raises(BridgeOperationError, match=r"no recording in it|not an MCAP file") as caught:
        export_can_log(BytesIO(content), out)
    assert isinstance(caught.value.__cause__, NotARecording)
    assert not out.exists()


def test_the_command_says_how_much_of_a_damaged_or_cut_recording_it_exported(request, tmp_path, capsys):
    whole = record_a_run(request.node.name)
    damaged, damaged_at = damage_a_middle_chunk(whole)
    cut = whole[: len(whole) // 2]
    for name, content, where in [
        ("damaged", damaged, f"damaged at byte {damaged_at}"),
        ("cut", cut, "cut short"),
    ]:
        source, out = tmp_path / f"{name}.mcap", tmp_path / f"{name}.log"
        source.write_bytes(content)
        assert main(["can", "export", str(source), str(out)]) == 1  # a script notices
        err = capsys.readouterr().err
        frames = len(out.read_text().splitlines())
        assert (
            frames > 0
            and f"{source} is {where}" in err
            and f"wrote the {frames} frames before it to {out}" in err
        )
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    assert main(["can", "export", str(empty), str(tmp_path / "empty.log")]) == 2
    assert f"{empty} is empty (0 bytes)" in capsys.readouterr().err
    assert not (tmp_path / "empty.log").exists()


def test_a_whole_recording_without_can_frames_is_refused_naming_what_it_has(tmp_path, capsys):
    """The peer's truth.mcap (no CAN side) exported by mistake: not an empty log and exit 0."""
    truth = tmp_path / "truth.mcap"
    with McapRecorder(truth) as recorder:
        recorder.publish("truth/pose", 0, {"timestamp": stamp(0), "x": 1.0})
    out = tmp_path / "truth.log"
    assert main(["can", "export", str(truth), str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{truth} has no can/frames records (it has truth/pose)" in err
    assert not out.exists()
