"""Hypothesis: the MCAP transactions, built a batch at a time by numpy, are what a plain reading
of the rule gives: a batch's open requests join those kept from earlier batches, then each
answer, in order, takes its request (the first answer to one takes it; later ones find
nothing); timed-out requests and broadcasts stand alone."""

from __future__ import annotations

import json
import os
from collections import OrderedDict
from dataclasses import replace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.message import NONE, ROLE_CODE, MessageBatch, Role
from sniffer.exports.levels import TIMEOUT
from sniffer.exports.transactions import KEPT_REQUESTS, TransactionEncoder
from tests.property.test_annotation_cache import exchanges, matched

EXAMPLES = int(os.environ.get("RTUSNIFF_EXAMPLES", "0"))
REQUEST, BROADCAST = ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.BROADCAST]


def expected(batches: list[tuple[MessageBatch, list[int]]]) -> list[tuple[int, int | None, str, str | None]]:
    """(request index, answer index, request hex, answer hex) of each transaction, batch by batch
    in the order of the rows that close them."""
    open_requests: OrderedDict[int, str] = OrderedDict()
    found = []
    for batch, kept in batches:
        first, rows = batch.frames.first_index, list(batch)
        for position in kept:
            message = rows[position]
            if message.role is Role.REQUEST and not message.flags & TIMEOUT:
                open_requests[first + position] = message.frame.data.hex()
        closed = []
        for position in kept:
            message = rows[position]
            if message.role in (Role.REQUEST, Role.BROADCAST):
                if message.role is Role.BROADCAST or message.flags & TIMEOUT:
                    closed.append((position, (first + position, None, message.frame.data.hex(), None)))
            elif message.request_index is not None:
                request = open_requests.pop(message.request_index, None)
                if request is not None:
                    closed.append((position, (message.request_index, first + position, request,
                                              message.frame.data.hex())))  # fmt: skip
        found += [transaction for _, transaction in sorted(closed)]
        while len(open_requests) > KEPT_REQUESTS:
            open_requests.popitem(last=False)
    return found


@settings(max_examples=max(300, EXAMPLES), deadline=None)
@given(st.lists(exchanges(), min_size=1, max_size=30), st.lists(st.integers(1, 60), max_size=3), st.data())
def test_transactions_follow_the_rule(traffic: list[list[bytes]], cuts: list[int], data: st.DataObject) -> None:
    batches, requests = [], [0]
    for fed in matched([frame for exchange in traffic for frame in exchange], tuple(cuts)):
        batch, first, earlier = fed, fed.frames.first_index, list(requests)
        requests += (first + np.flatnonzero(batch.role == REQUEST)).tolist()
        if data.draw(st.booleans()):  # pairings the matcher would not make: answers again, to others
            choices = st.one_of(st.just(NONE), st.integers(max(0, first - 4), first + len(batch) + 1),
                                st.sampled_from(requests), st.sampled_from(earlier[-8:]),
                                st.sampled_from(earlier))  # fmt: skip
            paired = data.draw(st.lists(choices, min_size=len(batch), max_size=len(batch)))
            batch = replace(batch, request_index=np.array(paired, np.int64))
        every_row = list(range(len(batch)))
        kept = every_row if data.draw(st.booleans()) else [row for row in every_row if data.draw(st.booleans())]
        batches.append((batch, kept))
    encoder, columns, got, in_columns = TransactionEncoder(), TransactionEncoder(), [], []
    for batch, kept in batches:
        rows, _ = encoder.rows(batch, np.array(kept, np.int64))
        for row in range(len(rows)):
            record = json.loads(rows.row(row))
            got.append((record["request_index"], record["answer_index"], record["request"], record["answer"]))
        # The Parquet table's columns, which spell no hex: the same transactions.
        found = columns.columns(batch, np.array(kept, np.int64))
        in_columns += [(request, None if answer == NONE else answer) for request, answer in
                       zip(found["request_index"].tolist(), found["answer_index"].tolist(), strict=True)]
    assert got == expected(batches)
    assert in_columns == [(request, answer) for request, answer, _, _ in got]
