"""Commands whose sinks only count (``stats``, ``compare``, ``cut``) decode the chunks read joined
into larger batches (:data:`sniffer.pipeline.COUNTING_BATCH_CHUNKS`), and so does the Parquet
dataset (:data:`sniffer.pipeline.JOINED_BATCH_CHUNKS`); the statistics and the dataset are the
same as from the batches as read, on the samples and on the real recordings. Other outputs that
annotate keep the readers' batches (their memory grows with a batch)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from decoders.capture import ChunkBatch
from decoders.message import MessageBatch
from decoders.pipeline import Decoder
from sniffer import pipeline
from sniffer.io import mcap_blocks, mcap_native
from sniffer.io.formats import text
from tests.conftest import CliResult
from tests.real_recordings import RECORDINGS, TEXT, available

CAPTURES = Path(__file__).resolve().parents[1] / "captures"
READ_CHUNKS = 4
CAPTURE_FILES = sorted(CAPTURES.glob("*.log")) + sorted(CAPTURES.glob("*.mcap"))
REAL = [TEXT / name for name in RECORDINGS]


@pytest.fixture
def fed(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """Small batches as read; the number of chunks of every batch the decoder is fed."""
    monkeypatch.setattr(text, "BATCH_CHUNKS", READ_CHUNKS)
    monkeypatch.setattr(mcap_blocks, "BATCH_CHUNKS", READ_CHUNKS)
    monkeypatch.setattr(mcap_native, "BATCH_CHUNKS", READ_CHUNKS)
    sizes: list[int] = []
    feed = Decoder.feed

    def counted(self: Decoder, batch: ChunkBatch) -> list[MessageBatch]:
        sizes.append(len(batch))
        return feed(self, batch)

    monkeypatch.setattr(Decoder, "feed", counted)
    yield sizes


def _both_ways(cli: Callable[..., CliResult], fed: list[int], monkeypatch: pytest.MonkeyPatch, constant: str,
               command: Callable[[int], list[str]]) -> list[str]:
    """``command(join)`` run with ``pipeline.<constant>`` at 0 (batches as read), then joining
    ``5 * READ_CHUNKS``: what each wrote on standard output. The same chunks were fed both times,
    joined the second where there were many."""
    outputs, batches = [], []
    for join in (0, 5 * READ_CHUNKS):
        monkeypatch.setattr(pipeline, constant, join)
        fed.clear()
        result = cli(*command(join))
        assert result.code == 0, result.err
        outputs.append(result.out)
        batches.append(list(fed))
    as_read, joined = batches
    assert sum(as_read) == sum(joined)
    if sum(as_read) > 5 * READ_CHUNKS and len(as_read) > 2:
        assert len(joined) < len(as_read) and max(joined) >= 5 * READ_CHUNKS, (as_read, joined)
    return outputs


def _stats_both_ways(cli: Callable[..., CliResult], capture: Path, fed: list[int],
                     monkeypatch: pytest.MonkeyPatch) -> None:
    outputs = _both_ways(cli, fed, monkeypatch, "COUNTING_BATCH_CHUNKS",
                         lambda _: ["stats", str(capture), "--format", "json"])
    assert outputs[0] == outputs[1]


@pytest.mark.parametrize("capture", CAPTURE_FILES, ids=[path.name for path in CAPTURE_FILES])
def test_stats_of_joined_batches_are_the_same(cli: Callable[..., CliResult], capture: Path, fed: list[int],
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    _stats_both_ways(cli, capture, fed, monkeypatch)


@pytest.mark.skipif(not available(), reason="../shared/real not present")
@pytest.mark.parametrize("capture", REAL, ids=[path.name for path in REAL])
def test_stats_of_real_recordings_joined_are_the_same(cli: Callable[..., CliResult], capture: Path, fed: list[int],
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    _stats_both_ways(cli, capture, fed, monkeypatch)


def _parquet_both_ways(cli: Callable[..., CliResult], capture: Path, fed: list[int], folder: Path,
                       monkeypatch: pytest.MonkeyPatch) -> None:
    from sniffer.exports.parquet_export import TABLES
    from tests.test_parquet import table

    _both_ways(cli, fed, monkeypatch, "JOINED_BATCH_CHUNKS", lambda join: [
        "export", str(capture), "--parquet", str(folder / f"joined-{join}"), "-q", "--profile", "atv71", "--jobs", "1"])
    for name in TABLES:
        assert table(folder / "joined-0", name) == table(folder / f"joined-{5 * READ_CHUNKS}", name), name


@pytest.mark.parametrize("capture", CAPTURE_FILES, ids=[path.name for path in CAPTURE_FILES])
def test_parquet_of_joined_batches_is_the_same(cli: Callable[..., CliResult], capture: Path, fed: list[int],
                                               tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _parquet_both_ways(cli, capture, fed, tmp_path, monkeypatch)


@pytest.mark.skipif(not available(), reason="../shared/real not present")
@pytest.mark.parametrize("capture", REAL, ids=[path.name for path in REAL])
def test_parquet_of_real_recordings_joined_is_the_same(cli: Callable[..., CliResult], capture: Path,
                                                       fed: list[int], tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    _parquet_both_ways(cli, capture, fed, tmp_path, monkeypatch)


def test_outputs_that_annotate_keep_the_batches_as_read(cli: Callable[..., CliResult], fed: list[int],
                                                        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """JSONL, MCAP, and the Parquet dataset written with either, keep the readers' batches;
    ``stats`` and the Parquet dataset alone join them."""
    monkeypatch.setattr(pipeline, "COUNTING_BATCH_CHUNKS", 5 * READ_CHUNKS)
    monkeypatch.setattr(pipeline, "JOINED_BATCH_CHUNKS", 5 * READ_CHUNKS)
    capture = CAPTURES / "atv71-plc-poll.log"
    for command in (["analyze", str(capture), "--format", "jsonl"],
                    ["export", str(capture), "--mcap", str(tmp_path / "out.mcap"),
                     "--parquet", str(tmp_path / "both")]):
        fed.clear()
        assert cli(*command, "--jobs", "1").code == 0
        assert sum(fed) > 5 * READ_CHUNKS and max(fed) < 5 * READ_CHUNKS, command
    for command in (["stats", str(capture)], ["export", str(capture), "--parquet", str(tmp_path / "alone")]):
        fed.clear()
        assert cli(*command, "--jobs", "1").code == 0
        assert max(fed) >= 5 * READ_CHUNKS, command


def test_two_processes_join_as_one(fed: list[int], monkeypatch: pytest.MonkeyPatch) -> None:
    """The decoding process joins the chunks for counting sinks as one process does: the same
    statistics, from as many batches, fewer than read."""
    from decoders.stats import Statistics
    from sniffer.io.registry import open_reader
    from sniffer.sinks import Sink

    class Counting(Sink):
        wants_statistics = True

    delivered: list[int] = []
    batch = pipeline.Delivery.batch

    def counted(self: pipeline.Delivery, *args: object) -> None:
        delivered.append(1)
        batch(self, *args)

    monkeypatch.setattr(pipeline.Delivery, "batch", counted)
    figures, batches = [], []
    for jobs, join in ((1, 0), (1, 5 * READ_CHUNKS), (2, 5 * READ_CHUNKS)):
        monkeypatch.setattr(pipeline, "COUNTING_BATCH_CHUNKS", join)
        delivered.clear()
        reader = open_reader(str(CAPTURES / "atv71-plc-poll.log"))
        statistics: Statistics = pipeline.analyze(
            reader, "poll", pipeline.Analysis(reader.info.line, reader.info.timing), [Counting()], jobs=jobs)
        figures.append(statistics.to_dict())
        batches.append(len(delivered))
    assert figures[0] == figures[1] == figures[2] and figures[0]["frames"]
    assert batches[1] == batches[2] < batches[0], batches


def test_batches_are_joined_only_where_every_sink_that_takes_messages_joins() -> None:
    from sniffer.sinks import Sink

    class Joining(Sink):
        wants_messages = True
        joins_batches = True

    class Plain(Sink):
        wants_messages = True

    class Chunks(Sink):
        wants_chunks = True

    class Counting(Sink):
        wants_statistics = True

    def joined(*sinks: Sink) -> tuple[int, int] | None:
        return pipeline.Delivery(list(sinks)).joined()

    counting = (pipeline.COUNTING_BATCH_CHUNKS, pipeline.COUNTING_BATCH_BYTES)
    assert joined(Counting()) == counting
    assert joined(Joining()) == joined(Joining(), Counting()) == (pipeline.JOINED_BATCH_CHUNKS,
                                                                  pipeline.COUNTING_BATCH_BYTES)
    assert joined(Joining(), Plain()) is None
    assert joined(Plain()) is None
    assert joined(Joining(), Chunks()) is None
    assert joined(Counting(), Chunks()) is None
