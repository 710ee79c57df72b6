"""The report's sections for studies: how a campaign stopped when decided (``refexmc run
--until-decided``, refexmc.campaign.decided). Hooked into :func:`refexmc.report.make_report` by
a few lines, so that the report's own modules stay as they are."""

MANIFEST_KEY = "until_decided"  # refexmc.campaign.decided.MANIFEST_KEY (which imports this package)


def format_stopping(record):
    from refexmc.campaign.decided import format_stopping as format_record

    return format_record(record)


def stopping(campaign):
    """The stopping record of a campaign flown with ``--until-decided`` (manifest.json), or None."""
    return campaign.manifest.get(MANIFEST_KEY)


def stopping_text(summary):
    """Lines for the terminal summary ('' for a campaign flown without ``--until-decided``)."""
    record = summary.get(MANIFEST_KEY)
    return "\n" + format_stopping(record) if record else ""


def stopping_html(summary):
    """An HTML section for the report page ('' without a stopping record)."""
    from html import escape

    record = summary.get(MANIFEST_KEY)
    if not record:
        return ""
    return (
        "<section id='until-decided'><h2>Stopping when decided</h2><pre>"
        + escape(format_stopping(record))
        + "</pre><p>Group-sequential rule: one-sided Clopper-Pearson bounds with the alpha of each "
        "requirement spent over the looks (Lan-DeMets, Pocock type); docs/studies.md.</p></section>"
    )
