"""The exports: MCAP, Rerun, pcap, the Parquet dataset, and the live viewers' streams."""

#: The Parquet dataset's tables (``export --parquet``, the library's ``Capture.table``); each but
#: the last has times.
TABLES = ("frames", "transactions", "values", "anomalies", "latencies")
