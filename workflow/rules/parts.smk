# Parts: DFT shape features per part (paper §3.2.1), the Fig. 6 reconstruction panel and the
# Supplementary Fig. S1 coefficient study. Parts are read from config["parts"]["dir"] only (the
# library is generated and committed by `feeder parts generate`; a user may drop in their own
# <id>.stl). A part's features come from its <id>.xyz face cloud when there is one, otherwise from
# its STL's top face. Uses PARTS, code() from common.smk. Figures are drawn by
# their own jobs (feeder figure ...) from data files, so a style edit redraws only that figure.


rule part_features:
    """45 raw DFT values of one part: results/features/{part}.json (docs/data.md)."""
    input:
        code("features"),
        stl=lambda w: f"{config['parts']['dir']}/{w.part}.stl",
        src=lambda w: (
            f"{config['parts']['dir']}/{w.part}.xyz"
            if exists(f"{config['parts']['dir']}/{w.part}.xyz")
            else f"{config['parts']['dir']}/{w.part}.stl"
        ),
    output:
        f"{RESULTS}/features/{{part}}.json",
    log:
        f"{LOGS}/features/{{part}}.log",
    benchmark:
        f"{BENCHMARKS}/features/{{part}}.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder features {input.src} --out {output} > {log} 2>&1"


rule parts_fig6_data:
    """Fig. 6 (panel b) data: outlines and their reconstructions from the kept DFT coefficients, for
    the parts listed in parts.fig6 that are in use (else the first eight parts)."""
    input:
        code("parts"),
        src=lambda w: [
            (
                f"{config['parts']['dir']}/{p}.xyz"
                if exists(f"{config['parts']['dir']}/{p}.xyz")
                else f"{config['parts']['dir']}/{p}.stl"
            )
            for p in ([q for q in config["parts"]["fig6"] if q in PARTS] or PARTS[:8])
        ],
    output:
        f"{RESULTS}/figdata/fig6_dft_reconstruction.npz",
    log:
        f"{LOGS}/features/fig6_data.log",
    benchmark:
        f"{BENCHMARKS}/features/fig6_data.tsv"
    conda:
        "../envs/feeder.yaml"
    shell:
        "feeder parts fig6-data {input.src} --out {output} > {log} 2>&1"


rule parts_s1:
    """Supplementary Fig. S1 table: reconstruction MSE over every protocol part vs the number of
    largest-magnitude coefficients kept (1 .. parts.s1_max_coefficients)."""
    input:
        code("parts"),
        src=lambda w: [
            (
                f"{config['parts']['dir']}/{p}.xyz"
                if exists(f"{config['parts']['dir']}/{p}.xyz")
                else f"{config['parts']['dir']}/{p}.stl"
            )
            for p in PROTOCOL_PARTS
        ],
    output:
        report(f"{RESULTS}/tables/s1_dft_mse.csv", caption="../report/s1_dft_mse_table.rst", category="Parts"),
    log:
        f"{LOGS}/features/s1.log",
    benchmark:
        f"{BENCHMARKS}/features/s1.tsv"
    conda:
        "../envs/feeder.yaml"
    params:
        max_coefficients=config["parts"]["s1_max_coefficients"],
    shell:
        "feeder parts s1 {input.src} --table {output} --max-coefficients {params.max_coefficients} > {log} 2>&1"
