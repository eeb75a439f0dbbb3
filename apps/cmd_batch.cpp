// `rangebayes batch submit|run-task|status|resubmit`: many subcommand lines on a Slurm cluster or on local
// worker processes (batch/submit.h, batch/task.h).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "apps/command.h"
#include "apps/flags.h"
#include "batch/submit.h"
#include "batch/task.h"
#include "core/error.h"

namespace rangebayes::apps {
namespace {

struct SubmitArgs {
  std::string manifest, out, dir;
  BatchSubmitOptions options;
};

// --task-timeout SECONDS, of submit and resubmit (for every task) and of run-task (for its one).
void AddTaskTimeoutOption(CLI::App* sub, double* seconds) {
  sub->add_option("--task-timeout", *seconds,
                  "Time limit of each task, in seconds (at most a year): its command gets SIGTERM, SIGKILL " +
                      FormatSeconds(kTaskTimeoutGraceS) +
                      " s later, and the task is recorded as timeout (resubmit runs it again). The same with --local "
                      "and on Slurm, where it also sets sbatch's --time (whole minutes, with room for that grace)")
      ->check(PositiveReal());
}

void AddSchedulingOptions(CLI::App* sub, SubmitArgs* a) {
  sub->add_option("--partition", a->options.partition, "Slurm partition (sbatch --partition); default: the cluster's");
  sub->add_option("--max-parallel", a->options.max_parallel,
                  "At most N tasks of the array at once (--array=...%N); 0: no limit")
      ->check(CLI::Range(0, 100000));
  sub->add_option("--slurm-arg", a->options.slurm_args,
                  "Extra sbatch argument, repeatable; write --slurm-arg=--time=1:00:00 for one that starts with -");
  sub->add_option("--local", a->options.local_workers,
                  "Run here with N worker processes instead of Slurm; returns when every task has ended")
      ->check(CLI::Range(1, 1024));
  AddTaskTimeoutOption(sub, &a->options.task_timeout_s);
}

void PrintTaskEnd(const BatchTaskStatus& s) {
  if (s.state == "succeeded") {
    std::printf("task %d: succeeded in %.2f s\n", s.index, s.duration_s);
  } else {
    std::printf("task %d: %s (exit %d) after %.2f s: %s\n", s.index, s.state.c_str(), s.exit_code, s.duration_s,
                s.error_line.c_str());
  }
  std::fflush(stdout);
}

// The options that name a file or folder a command writes, whatever the command: a new option that writes must be
// named so or added here (`learn-prior --plot` was missed, and its task wrote beside the manifest).
constexpr std::array<std::string_view, 5> kOutputOptionNames = {"out", "png", "plot", "record", "ui-record-dir"};

// Where each subcommand of `sub` names its outputs, from its own options: an option named in kOutputOptionNames
// (with its short name), and a positional named OUT, take output paths; a positional of several words whose help
// starts "IN OUT" (decimate's FILES) ends with its output unless an output option is given.
void AddSyntaxes(const CLI::App& parent, const std::string& prefix, SubcommandSyntaxes* syntaxes) {
  for (const CLI::App* sub : parent.get_subcommands([](const CLI::App*) { return true; })) {
    const std::string name = prefix + sub->get_name();
    if (name == "batch") continue;
    SubcommandSyntax syntax;
    for (const CLI::Option* opt : sub->get_options()) {
      if (opt->nonpositional()) {
        if (opt->get_type_size_max() <= 0) continue;  // a flag
        const bool output = std::any_of(opt->get_lnames().begin(), opt->get_lnames().end(), [](const std::string& l) {
          return std::find(kOutputOptionNames.begin(), kOutputOptionNames.end(), l) != kOutputOptionNames.end();
        });
        for (const std::string& l : opt->get_lnames()) {
          syntax.value_options.push_back("--" + l);
          if (output) syntax.output_options.push_back("--" + l);
        }
        for (const std::string& s : opt->get_snames()) {
          syntax.value_options.push_back("-" + s);
          if (output) syntax.output_options.push_back("-" + s);
        }
      } else if (opt->get_positional()) {
        SubcommandSyntax::Positional p;
        const int words = opt->get_items_expected_max();
        p.words = words >= 1000 ? -1 : words;
        p.output = opt->get_name() == "OUT";
        p.last_is_output = p.words != 1 && opt->get_description().rfind("IN OUT", 0) == 0;
        syntax.positionals.push_back(p);
      }
    }
    (*syntaxes)[name] = syntax;
    AddSyntaxes(*sub, name + " ", syntaxes);
  }
}

SubcommandSyntaxes Syntaxes(const CLI::App& app) {
  SubcommandSyntaxes syntaxes;
  AddSyntaxes(app, "", &syntaxes);
  return syntaxes;
}

// BatchSubmitOptions::check_line: a task line parsed by a second instance of the binary's own command line (MakeApp),
// so that what the parser refuses at the start of a task (an unknown option, a value an option's check refuses, a
// missing or extra argument) is refused at submit. Its top-level parse-complete callback, which CLI11 runs after
// parsing and before the subcommands' callbacks, ends the parse, so no command runs.
std::function<void(const std::vector<std::string>&)> TaskLineChecker() {
  struct Parsed {};
  std::shared_ptr<CLI::App> app = MakeApp();
  app->parse_complete_callback([] { throw Parsed{}; });
  return [app](const std::vector<std::string>& arguments) {
    std::vector<const char*> argv = {"rangebayes"};
    for (const std::string& a : arguments) argv.push_back(a.c_str());
    std::string problem;
    try {
      app->parse(static_cast<int>(argv.size()), argv.data());
      problem = "was not checked (its command would have run)";  // not reached: Parsed ends every parse
    } catch (const Parsed&) {
      return;
    } catch (const CLI::CallForHelp&) {
      problem = "--help shows help instead of running the task";
    } catch (const CLI::CallForAllHelp&) {
      problem = "--help-all shows help instead of running the task";
    } catch (const CLI::CallForVersion&) {
      problem = "--version shows the version instead of running the task";
    } catch (const CLI::ParseError& e) {
      problem = e.what();
    }
    for (char& c : problem) {
      if (c == '\n') c = ' ';
    }
    const std::string name = ParsedCommandName(*app);
    RB_FAIL(name.substr(name.find(' ') + 1), ": ", problem, " (see ", name, " --help)");
  };
}

// The exit code of batch status (and of a local submit or resubmit): 0 when every task succeeded; 3 when a task
// needs a rerun (failed, partial, changed, timeout or interrupted); else 4 while a task is running or missing
// (queued, not started yet, or never started).
int BatchExitCode(const BatchReport& report) {
  if (report.failed > 0 || report.partial > 0 || report.changed > 0 || report.timeout > 0 || report.interrupted > 0) {
    return 3;
  }
  if (report.running > 0 || report.missing > 0) return 4;
  return 0;
}

// After a local run: the counts and failures, and BatchExitCode (3 for a missing task too: none is left to run).
void FinishLocal(const BatchSubmitSummary& summary) {
  std::printf("%s\n", summary.BriefReport().c_str());
  const BatchReport report = CollectBatchReport(summary.dir);
  std::printf("%s", report.BriefReport().c_str());
  const int code = BatchExitCode(report);
  if (code != 0) SetExitCode(report.missing > 0 ? 3 : code);
}

void Submitted(const BatchSubmitSummary& summary) {
  if (summary.JobIds().empty()) {
    FinishLocal(summary);
    return;
  }
  std::printf("%s\n", summary.JobIds().c_str());
  std::fprintf(stderr, "%s; follow it with: rangebayes batch status %s\n", summary.BriefReport().c_str(),
               summary.dir.c_str());
}

void AddBatch(CLI::App& app) {
  CLI::App* batch = app.add_subcommand(
      "batch", "Run a manifest of subcommand lines as Slurm job arrays, or on local worker processes");
  batch->require_subcommand(1);

  {
    auto a = std::make_shared<SubmitArgs>();
    CLI::App* sub = batch->add_subcommand(
        "submit",
        "Submit every line of MANIFEST (one rangebayes subcommand per line, # comments) as one Slurm job array "
        "(one per MaxArraySize tasks when the batch has more); prints the job ids. Each line is first parsed as the "
        "subcommand would parse it: a mistyped option or bad "
        "value refuses the batch, naming the line. Inputs are paths relative to the manifest's folder, outputs "
        "relative to the task's "
        "folder DIR/tasks/<index>/ (README, Batch processing)");
    sub->add_option("MANIFEST", a->manifest, "Manifest file")->required()->check(CLI::ExistingFile);
    sub->add_option("--out,-o", a->out, "Batch folder DIR (created; must not hold a batch yet)")->required();
    AddSchedulingOptions(sub, a.get());
    sub->callback([a, &app] {
      if (a->options.local_workers > 0) a->options.on_task_end = PrintTaskEnd;
      for (const CLI::App* command : app.get_subcommands([](CLI::App*) { return true; })) {
        if (command->get_name() != "batch") a->options.subcommands.push_back(command->get_name());
      }
      a->options.syntaxes = Syntaxes(app);
      a->options.check_line = TaskLineChecker();
      Submitted(SubmitBatch(a->manifest, a->out, a->options));
    });
  }
  {
    auto a = std::make_shared<SubmitArgs>();
    CLI::App* sub = batch->add_subcommand(
        "resubmit", "Submit exactly the missing and failed tasks of DIR again, as new job arrays (or --local N)");
    sub->add_option("DIR", a->dir, "Batch folder")->required();
    AddSchedulingOptions(sub, a.get());
    sub->add_flag("--include-running", a->options.include_running,
                  "Also the tasks whose status still says running: a --local run on another host that died, which "
                  "batch status names but cannot check. Only when you know they are not running (refused while a "
                  "Slurm job of the batch is queued, or for a task whose run-task runs on this host)");
    sub->callback([a, &app] {
      if (a->options.local_workers > 0) a->options.on_task_end = PrintTaskEnd;
      a->options.syntaxes = Syntaxes(app);
      a->options.check_line = TaskLineChecker();
      Submitted(ResubmitBatch(a->dir, a->options));
    });
  }
  {
    struct Args {
      std::string dir;
      int index = 0;
      double task_timeout_s = 0;
    };
    auto a = std::make_shared<Args>();
    CLI::App* sub = batch->add_subcommand(
        "run-task",
        "Run task I of DIR (what each array task runs): in a temporary folder renamed to DIR/tasks/I/ only on "
        "success; writes DIR/status/I.json; exits with the task's exit code");
    sub->add_option("DIR", a->dir, "Batch folder")->required();
    sub->add_option("I", a->index, "Task index (0-based, manifest order)")->required()->check(NonNegativeInteger());
    AddTaskTimeoutOption(sub, &a->task_timeout_s);
    sub->callback([a, &app] {
      RunTaskOptions options;
      options.task_timeout_s = a->task_timeout_s;
      options.syntaxes = Syntaxes(app);
      const BatchTaskStatus s = RunBatchTask(a->dir, a->index, options);
      PrintTaskEnd(s);
      if (s.state != "succeeded") SetExitCode(s.exit_code > 0 && s.exit_code < 256 ? s.exit_code : 1);
    });
  }
  {
    struct Args {
      std::string dir;
      bool json = false;
    };
    auto a = std::make_shared<Args>();
    CLI::App* sub = batch->add_subcommand(
        "status",
        "Counts of succeeded, partial, changed, failed, timeout, running, interrupted and missing tasks of DIR, "
        "and each failure's error line. Exit 0: all succeeded; 3: some need a rerun (failed, partial, changed, "
        "timeout, interrupted); 4: none of those, but some are running or missing (not started)");
    sub->add_option("DIR", a->dir, "Batch folder")->required();
    sub->add_flag("--json", a->json, "Print JSON (every task with its status file)");
    sub->callback([a] {
      const BatchReport report = CollectBatchReport(a->dir);
      std::printf("%s", a->json ? report.Json().c_str() : report.BriefReport().c_str());
      SetExitCode(BatchExitCode(report));
    });
  }
  {
    auto dir = std::make_shared<std::string>();
    CLI::App* sub = batch->add_subcommand(
        "cancel",
        "Cancel (scancel) every Slurm job of DIR that is still queued or running; then batch status DIR "
        "says what ended, and batch resubmit DIR runs the rest");
    sub->add_option("DIR", *dir, "Batch folder")->required();
    sub->callback([dir] {
      std::string ids;
      for (const std::string& id : CancelBatch(*dir, BatchSubmitOptions{})) ids += (ids.empty() ? "" : " ") + id;
      std::printf("cancelled Slurm job%s %s of %s\n", ids.find(' ') == std::string::npos ? "" : "s", ids.c_str(),
                  BatchLayout(*dir).dir.c_str());
    });
  }
}

}  // namespace

RB_REGISTER_COMMANDS(80, AddBatch);

}  // namespace rangebayes::apps
