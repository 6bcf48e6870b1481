"""The Parquet dataset in Spark, as the README shows it: read as written (no settings), and the
documented queries giving DuckDB's answers to the last digit, which are ``stats``' percentiles
(the nearest rank). Captures decoded in Spark's executors (``sniffer.spark``): written by Spark's
own writer, the dataset ``export --each --parquet`` writes, row for row; a damaged capture a row
of the errors table.

A local Spark session (Java 17 or later), bound to the loopback interface only. Marked ``spark``:
CI runs them; ``-m 'not spark'`` leaves them out where there is no Java."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import sniffer
import sniffer.spark
from benchmarks import generate_capture
from decoders.line import LineSettings
from tests.conftest import ROOT
from tests.test_parquet import DOCUMENTS, P95_HISTOGRAM_QUERY, P95_QUERY, dataset, duckdb  # noqa: F401 - a fixture

pytestmark = [pytest.mark.spark,
              pytest.mark.skipif(shutil.which("java") is None and not os.environ.get("CI"), reason="no Java")]


def readme_spark() -> str:
    """The README's Spark example (its dataset folder: ``{dataset}``)."""
    text = "".join(document.read_text(encoding="utf-8") for document in DOCUMENTS)
    (block,) = [block for block in re.findall(r"```python\n(.*?)```", text, re.DOTALL) if "spark.sql(" in block]
    return block.replace('"plant/', '"{dataset}/')


@pytest.fixture(scope="module")
def spark() -> Iterator[Any]:
    os.environ["SPARK_LOCAL_IP"] = "127.0.0.1"  # the driver listens on loopback only
    from pyspark.sql import SparkSession

    os.environ["PYSPARK_PYTHON"] = sys.executable  # the executors' Python: this one, with rtusniff
    session = (SparkSession.builder.master("local[2]").appName("rtusniff-tests")
               .config("spark.driver.bindAddress", "127.0.0.1").config("spark.driver.host", "127.0.0.1")
               .config("spark.ui.enabled", "false").config("spark.sql.shuffle.partitions", "2")
               .config("spark.sql.session.timeZone", "UTC").getOrCreate())
    session.sparkContext.setLogLevel("ERROR")
    yield session
    session.stop()


def rows(result: Any) -> list[tuple[Any, ...]]:
    return [tuple(str(value) if name == "date" else value for name, value in row.asDict().items()) for row in result]


def duck(query: str) -> list[tuple[Any, ...]]:
    result = duckdb.sql(query)
    return [tuple(str(value) if name == "date" else value for name, value in zip(result.columns, row, strict=True))
            for row in result.fetchall()]


def test_the_dataset_in_spark(spark: Any, dataset: Path, capsys: pytest.CaptureFixture[str],  # noqa: F811
                              tmp_path: Path) -> None:
    """One test, so that one Spark session starts (the workers of ``-n 2`` would start one each)."""
    the_readme_spark_query_gives_duckdb_s_answers(spark, dataset, capsys)
    the_histogram_query_runs_on_spark_as_it_is(spark, dataset)
    for table in ("frames", "transactions", "values", "anomalies"):
        times_read_as_written(spark, dataset, table)
    the_documented_cluster_job_gives_the_export_s_dataset(spark, tmp_path, capsys)


def the_documented_cluster_job_gives_the_export_s_dataset(spark: Any, folder: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """docs/api.md's Spark example, run on a ``captures/`` of 20 generated captures (drives
    polled, exact and host timing) and a damaged one: written by Spark's writer, the dataset
    ``export --each --parquet`` writes, row for row; the damaged capture the errors table's row,
    with the command line's exit code and error line."""
    captures = folder / "captures"
    captures.mkdir()
    for seed in range(20):
        generate_capture.write(captures / f"line-{seed:02d}.log", 300, seed, LineSettings.parse("19200 8E1"),
                               "exact" if seed % 2 else "host", values="steady")
    (captures / "damaged.log").write_text("# rtu-capture v1\n# line: 19200 8E1\n1.0 0103\n2.0 zz\n")
    export = subprocess.run([sys.executable, "-m", "sniffer", "export", "--each", str(captures), "--parquet",
                             str(folder / "exported"), "--profile", "atv71", "--jobs", "1", "-q"],
                            capture_output=True, text=True, check=False)
    assert export.returncode == 15, export.stderr  # the damaged capture failed, the others were done
    (said,) = [line for line in export.stderr.splitlines() if "damaged.log" in line]

    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    (block,) = [block for block in re.findall(r"```python\n(.*?)```", text, re.DOTALL) if "sniffer.spark" in block]
    namespace: dict[str, Any] = {"dataset": str(folder / "spark")}
    # Spark's JVM reads a relative path from its own working folder: the example's, made absolute.
    exec(compile(block.replace('"captures/', f'"{folder}/captures/'), "docs/api.md (Spark)", "exec"), namespace)
    shown = capsys.readouterr().out
    assert re.search(r"damaged\.log\s*\|7\s*\|error: file:", shown), shown  # the errors table, as shown
    for name in sniffer.TABLES:
        ours, theirs = dataset_rows(folder / "spark", name), dataset_rows(folder / "exported", name)
        assert len(ours) == len(theirs) > 20 and ours == theirs, name
    ((path, code, line),) = [tuple(row) for row in namespace["tables"]["errors"].collect()]
    assert path.endswith("/damaged.log") and code == 7
    assert line.split("damaged.log")[1] == said.split("damaged.log")[1]  # ":line 4: bad hex digit 'z'"


def dataset_rows(folder: Path, table: str) -> list[str]:
    """A dataset's rows of ``table``, each as text, sorted: partitions as text, times without
    their zone (pyarrow reads Spark's as local times of UTC), dictionaries as their values,
    ``capture`` the file's name (Spark names it by its URI)."""
    import pyarrow.dataset as ds

    rows = []
    for read in ds.dataset(str(folder / table), format="parquet", partitioning="hive").to_table().to_pylist():
        row = {key: (str(value) if key in ("bus", "date") else value) for key, value in read.items()}
        if "capture" in row:
            row["capture"] = Path(row["capture"]).name
        for key in ("t", "t_end"):
            if key in row:
                row[key] = row[key].replace(tzinfo=None).isoformat()
        rows.append(repr(sorted(row.items())))
    return sorted(rows)


def the_readme_spark_query_gives_duckdb_s_answers(spark: Any, dataset: Path,  # noqa: F811 - the fixture
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    example = readme_spark().format(dataset=dataset)
    exec(compile(example, "README.md (Spark)", "exec"), {})  # as a user pastes it: it runs and shows
    assert "latency_p95_ms" in capsys.readouterr().out
    (query,) = re.findall(r'spark\.sql\("""(.*?)"""\)', example, re.DOTALL)
    on_spark = rows(spark.sql(query).collect())
    on_duckdb = duck(P95_QUERY.format(dataset=dataset))
    assert on_spark == on_duckdb and len(on_spark) >= 8
    assert ("atv71-plc-poll", "2023-11-14", 2, 8, 5.996079) in on_spark  # stats: 6.00 ms


def the_histogram_query_runs_on_spark_as_it_is(spark: Any, dataset: Path) -> None:  # noqa: F811
    spark.read.parquet(str(dataset / "latencies")).createOrReplaceTempView("latencies")
    query = re.sub(r"read_parquet\('\{dataset\}/latencies/[^)]*\)", "latencies", P95_HISTOGRAM_QUERY)
    assert query != P95_HISTOGRAM_QUERY
    on_spark = rows(spark.sql(query).collect())
    assert on_spark == duck(P95_HISTOGRAM_QUERY.format(dataset=dataset)) and on_spark


def times_read_as_written(spark: Any, dataset: Path, table: str) -> None:  # noqa: F811
    """Every time column is a timestamp in Spark, of the microseconds of its exact ``_ns`` twin,
    and DuckDB reads the same instants."""
    frame = spark.read.parquet(str(dataset / table))
    kinds = dict(frame.dtypes)
    names = [name for name in ("t", "t_end") if name in kinds]
    assert names and all(kinds[name] == "timestamp" and kinds[f"{name}_ns"] == "bigint" for name in names), table
    for name in names:
        mismatched = frame.where(f"unix_micros({name}) != {name}_ns div 1000").count()
        assert mismatched == 0, (table, name)
        first = frame.selectExpr(f"min(unix_micros({name}))", f"min({name}_ns)").first()
        source = f"read_parquet('{dataset}/{table}/*/*/*.parquet', hive_partitioning = true)"
        assert tuple(first) == duckdb.sql(f"SELECT min(epoch_us({name})), min({name}_ns) FROM {source}").fetchall()[0]
