"""Record encoders shared by the views and the exports: JSON records a batch at a time
(``rows``: columns joined into rows; ``blocks``: fixed-width fields laid out by numpy;
``records``: the capture, frame and device records)."""
