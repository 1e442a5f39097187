"""Base of the Pandera models whose tables hold exactly their declared columns."""

from __future__ import annotations

import pandera.pandas as pa


class StrictModel(pa.DataFrameModel):
    """A table with exactly the declared columns: an undeclared column fails validation."""

    class Config:
        """Exactly these columns."""

        strict = True
