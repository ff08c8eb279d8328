"""Where a trial sits in its campaign, as its recording keeps it (the ``trial`` metadata).

``rover logs report CAMPAIGN_DIR`` reads only the recordings, so each one says which campaign terrain
(two terrains may share a terrain class: field-a and field-b, both sandy) and which variant it ran, and
where both stand in the campaign file, so the report keeps the campaign's order (its first variant is
the baseline every other one is compared with).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class CampaignPlace:
    terrain: str
    variant: str
    terrain_index: int  # position of the terrain in the campaign file, from 0
    variant_index: int  # position of the variant in the campaign file, from 0

    def metadata(self) -> dict[str, str]:
        """The ``trial`` metadata keys (all values are strings in MCAP metadata)."""
        return {
            "terrain": self.terrain,
            "variant": self.variant,
            "terrain_index": str(self.terrain_index),
            "variant_index": str(self.variant_index),
        }
