"""Which profile applies to which slave: the book a command's profile options make.

Apart from the applier (:mod:`decoders.profiles.apply`), which needs the PDU parsers: loading
the profiles imports only their model, before the decoding process is forked (see
:class:`sniffer.pipeline.Delivery`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from decoders.profiles.model import Profile


@dataclass
class ProfileBook:
    """Which profile applies to which slave.

    ``automatic``: a slave that identifies itself gets the profile its product code
    names, unless one was chosen for it; off when the user chose one profile for all.
    """

    default: Profile
    known: dict[str, Profile]
    per_slave: dict[int, Profile] = field(default_factory=dict)
    automatic: bool = True
    _identified: dict[int, Profile] = field(default_factory=dict)

    def profile_for(self, slave: int | None) -> Profile:
        if slave is None:
            return self.default
        return self.per_slave.get(slave) or self._identified.get(slave) or self.default

    def identify(self, slave: int, product_code: str) -> Profile | None:
        """The profile a product code names; it applies to ``slave`` from now on unless
        the user chose one for that slave."""
        profile = self.named_by(product_code)
        if profile is not None and self._identifies(slave):
            self._identified[slave] = profile
        return profile

    def profile_after(self, slave: int, product_code: str) -> Profile:
        """The profile ``slave`` would have once it said it is ``product_code`` (:meth:`identify`,
        nothing changed here)."""
        profile = self.named_by(product_code)
        return profile if profile is not None and self._identifies(slave) else self.profile_for(slave)

    def _identifies(self, slave: int) -> bool:
        """Whether what ``slave`` says it is chooses its profile (none was chosen for it)."""
        return self.automatic and slave not in self.per_slave

    def named_by(self, product_code: str) -> Profile | None:
        """The profile ``product_code`` names, if any."""
        for profile in self.known.values():
            if any(product_code.upper().startswith(code.upper()) for code in profile.product_codes):
                return profile
        return None
