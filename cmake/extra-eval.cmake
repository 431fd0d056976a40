# roe eval --plot and roe report: scripts/plot_run.py compiled into roe_app (cmake/embed.cmake), so the
# binary can render the figures wherever it runs (it writes the script to a temporary file and runs
# /usr/bin/python3 on it).
roe_embed_file(roe_app embedded_plot_run_script ${CMAKE_SOURCE_DIR}/scripts/plot_run.py)
